#include "cdc/graph/g2o.hpp"

#include "cdc/graph/objective.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <set>
#include <sstream>
#include <utility>

namespace cdc::graph {
namespace {

// GTSAM symbols name robots a..z; a cdc key of robot 0..25 is read from and written as such a symbol.
constexpr uint64_t kSymbolRobots = 26;

struct LineReader {
  const std::string& path;
  size_t line;
  std::istringstream in;
  bool* symbols = nullptr;       // set when an id carries a robot letter in its top byte
  bool* low_plain = nullptr;     // set when an id's top byte is below 26: read as such, a cdc key of robot 0..25
  std::string* plain = nullptr;  // the first id with no robot letter (a..z) in its top byte, with its line

  [[noreturn]] void fail(const std::string& msg) const {
    throw G2oError(path + ":" + std::to_string(line) + ": " + msg);
  }
  std::string token(const char* what) {
    std::string tok;
    if (!(in >> tok)) {
      fail(std::string("missing ") + what);
    }
    return tok;
  }
  template <class T>
  static bool parse(const std::string& tok, T& v) {
    auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    return ec == std::errc() && p == tok.data() + tok.size();
  }
  double number(const char* what) {
    const std::string tok = token(what);
    double v = 0;
    if (!parse(tok, v) || !std::isfinite(v)) {
      fail(std::string(what) + ": '" + tok + "' is not a finite number");
    }
    return v;
  }
  uint64_t id(const char* what) {
    const std::string tok = token(what);
    uint64_t v = 0;
    if (!parse(tok, v)) {
      fail(std::string(what) + ": '" + tok + "' is not a vertex id");
    }
    if (symbols != nullptr && (v >> 56) >= 'a' && (v >> 56) <= 'z') {
      *symbols = true;
    }
    if (low_plain != nullptr && (v >> 56) < kSymbolRobots) {
      *low_plain = true;
    }
    if (plain != nullptr && plain->empty() && ((v >> 56) < 'a' || (v >> 56) > 'z')) {
      *plain = path + ":" + std::to_string(line) + ": id " + std::to_string(v);
    }
    return v;
  }
  void expect_end() {
    std::string extra;
    if (in >> extra) {
      fail("unexpected extra value '" + extra + "'");
    }
  }
};

Eigen::Quaterniond read_quat(LineReader& r) {
  const double qx = r.number("qx");
  const double qy = r.number("qy");
  const double qz = r.number("qz");
  const double qw = r.number("qw");
  Eigen::Quaterniond q(qw, qx, qy, qz);
  if (std::abs(q.norm() - 1.0) > 1e-2) {
    r.fail("quaternion norm " + std::to_string(q.norm()) + " is not 1");
  }
  return q.normalized();
}

// A 3D pose as g2o writes it: x, y, z (named by the caller), then the quaternion qx qy qz qw.
Eigen::Isometry3d read_se3(LineReader& r, const char* x_name, const char* y_name, const char* z_name) {
  const double x = r.number(x_name);  // one statement each: argument order is unspecified
  const double y = r.number(y_name);
  const double z = r.number(z_name);
  const Eigen::Quaterniond q = read_quat(r);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

Eigen::Isometry3d planar(double x, double y, double theta) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, 0);
  T.linear() = Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// Two readings of one pose agree to the precision a g2o file carries.
bool same_pose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  const double scale = 1.0 + a.translation().norm();
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff() <= 1e-6 * scale;
}

bool positive_definite(const Matrix6d& info) {
  return Eigen::SelfAdjointEigenSolver<Matrix6d>(info).eigenvalues().minCoeff() > 0.0;
}

// Fails unless the information is positive definite or, with `isotropic`, gives positive SE-Sync
// weights. Returns whether it is positive definite.
bool check_information(LineReader& r, const Matrix6d& info, int dimension, bool isotropic) {
  if (isotropic) {
    Factor f;
    f.information = info;
    const IsotropicWeights w = isotropic_weights(f, dimension);
    if (!(std::isfinite(w.tau) && w.tau > 0.0 && std::isfinite(w.kappa) && w.kappa > 0.0)) {
      r.fail("information gives no positive isotropic weights (tau " + std::to_string(w.tau) + ", kappa " +
             std::to_string(w.kappa) + ")");
    }
    return positive_definite(info);
  }
  Eigen::SelfAdjointEigenSolver<Matrix6d> es(info);
  if (es.eigenvalues().minCoeff() <= 0.0) {
    r.fail("information matrix is not positive definite (smallest eigenvalue " +
           std::to_string(es.eigenvalues().minCoeff()) + ")");
  }
  return true;
}

// Where a file's records go: the graph, and the edges already read from other robots' files
// (null: a single file); the vertices declared by this file (id -> line and pose) and by every file so far.
// An edge as read, with the file it came from (its index in the folder).
struct EdgeRecord {
  size_t file;
  Eigen::Isometry3d T;
  Matrix6d info;
};
using EdgeRecords = std::map<std::pair<Key, Key>, std::vector<EdgeRecord>>;

struct Target {
  PoseGraph& graph;
  EdgeRecords& edges;  // every edge read so far, by its ends
  size_t file;         // this file's index in the folder
  bool folder;
  bool isotropic_information;
  std::set<Key>& declared;
  G2oReadReport& report;
  std::map<Key, std::pair<size_t, Eigen::Isometry3d>> in_file;

  void add_vertex(const LineReader& r, uint64_t raw, const Eigen::Isometry3d& T) {
    const Key k = from_g2o_key(raw);
    const auto [it, fresh] = in_file.emplace(k, std::make_pair(r.line, T));
    if (!fresh) {
      if (!same_pose(it->second.second, T)) {
        r.fail("vertex " + std::to_string(raw) + " declared again with a different pose (first on line " +
               std::to_string(it->second.first) + ")");
      }
      return;
    }
    if (declared.insert(k).second) {
      graph.poses[k] = T;
    } else if (!same_pose(graph.poses[k], T)) {
      ++report.conflicting_vertices;  // another file's estimate of the same pose: the first file's is kept
    }
  }

  // An edge another file listed alike is the same measurement (both robots list an inter-robot
  // edge): kept once. Any other edge between the same two poses is a measurement of its own.
  void add_edge(Key a, Key b, const Eigen::Isometry3d& T, const Matrix6d& info, bool definite) {
    std::vector<EdgeRecord>& same_ends = edges[{a, b}];
    const bool listed_elsewhere = std::any_of(same_ends.begin(), same_ends.end(), [&](const EdgeRecord& e) {
      return e.file != file && same_pose(e.T, T) && (e.info - info).cwiseAbs().maxCoeff() <= 1e-9 * info.norm();
    });
    if (listed_elsewhere) {
      ++report.duplicate_edges;
      return;
    }
    if (!same_ends.empty() || edges.count({b, a}) != 0) ++report.parallel_edges;
    if (!definite) ++report.indefinite_information;
    same_ends.push_back({file, T, info});
    graph.add_between(a, b, T, info);
  }
};

// The edge's two vertex ids; fails for an edge from a vertex to itself (checked once the line is read).
std::pair<Key, Key> read_edge_ends(LineReader& r) {
  const Key a = from_g2o_key(r.id("from id"));
  const Key b = from_g2o_key(r.id("to id"));
  return {a, b};
}

void check_edge_ends(LineReader& r, Key a, Key b) {
  if (a == b) {
    r.fail("edge from a vertex to itself");
  }
}

void read_vertex_se3(LineReader& r, Target& target) {
  const uint64_t id = r.id("vertex id");
  const Eigen::Isometry3d T = read_se3(r, "x", "y", "z");
  r.expect_end();
  target.add_vertex(r, id, T);
}

void read_vertex_se2(LineReader& r, Target& target) {
  const uint64_t id = r.id("vertex id");
  const double x = r.number("x");
  const double y = r.number("y");
  const double th = r.number("theta");
  r.expect_end();
  target.add_vertex(r, id, planar(x, y, th));
}

// EDGE_SE3:QUAT: the measurement and the upper triangle of the 6x6 information, row by row.
void read_edge_se3(LineReader& r, Target& target) {
  const auto [a, b] = read_edge_ends(r);
  const Eigen::Isometry3d T = read_se3(r, "tx", "ty", "tz");
  Matrix6d info;
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j) {
      info(i, j) = info(j, i) = r.number("information entry");
    }
  }
  r.expect_end();
  check_edge_ends(r, a, b);
  const bool definite = check_information(r, info, 3, target.isotropic_information);
  target.add_edge(a, b, T, info, definite);
}

// EDGE_SE2: (dx, dy, dtheta) and the upper triangle of its 3x3 information, lifted into 3D.
void read_edge_se2(LineReader& r, Target& target) {
  const auto [a, b] = read_edge_ends(r);
  const double dx = r.number("dx");
  const double dy = r.number("dy");
  const double dth = r.number("dtheta");
  const double i11 = r.number("I11");
  const double i12 = r.number("I12");
  const double i13 = r.number("I13");
  const double i22 = r.number("I22");
  const double i23 = r.number("I23");
  const double i33 = r.number("I33");
  r.expect_end();
  check_edge_ends(r, a, b);
  // (x, y, theta) -> (tx, ty, tz, rx, ry, rz): theta is rz; z, roll, pitch held planar.
  Matrix6d info = Matrix6d::Zero();
  info(0, 0) = i11;
  info(0, 1) = info(1, 0) = i12;
  info(1, 1) = i22;
  info(0, 5) = info(5, 0) = i13;
  info(1, 5) = info(5, 1) = i23;
  info(5, 5) = i33;
  info(2, 2) = info(3, 3) = info(4, 4) = kPlanarLiftInformation;
  const bool definite = check_information(r, info, 2, target.isotropic_information);
  target.add_edge(a, b, planar(dx, dy, dth), info, definite);
}

// The records read, each with its reader and the dimension it speaks of.
struct RecordKind {
  const char* tag;
  void (*read)(LineReader& r, Target& target);
  int dimension;
};
constexpr std::array<RecordKind, 4> kRecordKinds{{{"VERTEX_SE3:QUAT", read_vertex_se3, 3},
                                                  {"VERTEX_SE2", read_vertex_se2, 2},
                                                  {"EDGE_SE3:QUAT", read_edge_se3, 3},
                                                  {"EDGE_SE2", read_edge_se2, 2}}};

// The dimension a record speaks of: none (FIX), 2 or 3.
int read_record(const std::string& tag, LineReader& r, Target& target) {
  for (const RecordKind& kind : kRecordKinds) {
    if (tag == kind.tag) {
      kind.read(r, target);
      return kind.dimension;
    }
  }
  if (tag == "FIX") {
    return 0;  // the solver fixes the gauge itself
  }
  r.fail("unsupported record '" + tag + "' (expected VERTEX_SE3:QUAT, EDGE_SE3:QUAT, VERTEX_SE2, EDGE_SE2)");
}

// Reads one line's record into the target; a malformed line fails, or is skipped and counted.
// Returns the dimension the record speaks of (0: none or skipped).
int read_line(LineReader& r, Target& target, const G2oReadOptions& options) {
  std::string tag;
  if (!(r.in >> tag) || tag[0] == '#') {
    return 0;
  }
  try {
    return read_record(tag, r, target);
  } catch (const G2oError& e) {
    if (!options.skip_malformed) {
      throw;
    }
    ++target.report.skipped_lines;
    if (options.warnings != nullptr) {
      options.warnings->push_back(std::string(e.what()) + " (line skipped)");
    }
  }
  return 0;
}

void parse_into(const std::string& path, Target& target, const G2oReadOptions& options) {
  std::ifstream file(path);
  if (!file) {
    throw G2oError(path + ": cannot open file");
  }
  PoseGraph& graph = target.graph;
  std::string text, plain;
  size_t n = 0;
  bool saw_2d = false, saw_3d = false, low_plain = false;
  while (std::getline(file, text)) {
    LineReader r{path, ++n, std::istringstream(text)};
    r.symbols = &graph.symbol_keys;
    r.low_plain = &low_plain;
    r.plain = &plain;
    const int dimension = read_line(r, target, options);
    saw_2d = saw_2d || dimension == 2;
    saw_3d = saw_3d || dimension == 3;
  }
  if (saw_2d && saw_3d) {
    throw G2oError(path + ": mixes 2D and 3D records");
  }
  if (target.folder && !plain.empty()) {
    throw G2oError(plain + " carries no robot letter (a..z in its top byte): every file of a multi-robot folder " +
                   "keys its poses as GTSAM symbols of its robot");
  }
  if (low_plain && graph.symbol_keys) {
    throw G2oError(path +
                   ": mixes GTSAM symbol ids (a..z in the top byte) with plain ids whose top byte is below 26, " +
                   "which the symbols' keys would collide with");
  }
  if (saw_2d) {
    graph.dimension = 2;
  }
}

// Once every file is read: where vertices were declared, every edge's ends must be among them; where none
// were, every pose is implicit. Fills the report.
void check_vertices(const std::string& where, const PoseGraph& graph, const std::set<Key>& declared,
                    G2oReadReport& report) {
  report.vertices = declared.size();
  std::set<Key> named;
  for (const Factor& f : graph.factors) {
    named.insert(f.a);
    named.insert(f.b);
  }
  if (declared.empty()) {
    report.implicit_vertices = named.size();
    return;
  }
  size_t missing = 0;
  Key example = 0;
  for (const Key k : named) {
    if (declared.count(k) == 0 && missing++ == 0) example = k;
  }
  if (missing > 0) {
    throw G2oError(where + ": edges name " + std::to_string(missing) + " vertices no VERTEX line declares (" +
                   std::to_string(to_g2o_key(graph, example)) + " the first); where a graph declares vertices, it " +
                   "must declare every vertex its edges use");
  }
}

void finish_report(const G2oReadOptions& options, const G2oReadReport& report) {
  if (options.report != nullptr) *options.report = report;
}

}  // namespace

uint64_t to_g2o_key(const PoseGraph& graph, Key key) {
  if (!graph.symbol_keys || robot_of(key) >= kSymbolRobots) {
    return key;  // a plain id (its top byte names no robot a..z) is written as it was read
  }
  return (uint64_t{'a' + robot_of(key)} << 56) | index_of(key);
}

Key from_g2o_key(uint64_t raw) {
  const uint64_t top = raw >> 56;
  if (top >= 'a' && top <= 'z') {
    return make_key(static_cast<uint32_t>(top - 'a'), index_of(raw));
  }
  return raw;
}

PoseGraph read_g2o(const std::string& path, const G2oReadOptions& options) {
  PoseGraph g;
  std::set<Key> declared;
  G2oReadReport report;
  EdgeRecords edges;
  Target target{g, edges, 0, false, options.isotropic_information, declared, report, {}};
  parse_into(path, target, options);
  if (g.factors.empty() && g.poses.empty()) {
    throw G2oError(path + ": no vertices or edges");
  }
  check_vertices(path, g, declared, report);
  finish_report(options, report);
  return g;
}

PoseGraph read_g2o_folder(const std::string& folder, const G2oReadOptions& options) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(folder)) {
    throw G2oError(folder + ": not a folder");
  }
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder)) {
    if (e.is_regular_file() && e.path().extension() == ".g2o") {
      files.push_back(e.path());
    }
  }
  if (files.empty()) {
    throw G2oError(folder + ": no .g2o files");
  }
  std::sort(files.begin(), files.end());
  PoseGraph g;
  EdgeRecords edges;
  std::set<Key> declared;
  G2oReadReport report;
  for (size_t i = 0; i < files.size(); ++i) {
    Target target{g, edges, i, true, options.isotropic_information, declared, report, {}};
    parse_into(files[i].string(), target, options);
  }
  check_vertices(folder, g, declared, report);
  finish_report(options, report);
  return g;
}

void write_g2o(const std::string& path, const PoseGraph& graph) {
  std::ofstream out(path);
  if (!out) {
    throw G2oError(path + ": cannot create file");
  }
  out << std::setprecision(17);
  for (const auto& [k, T] : graph.poses) {
    const Eigen::Quaterniond q(T.rotation());
    const Eigen::Vector3d t = T.translation();
    if (graph.dimension == 2) {
      out << "VERTEX_SE2 " << k << ' ' << t.x() << ' ' << t.y() << ' ' << std::atan2(T(1, 0), T(0, 0)) << '\n';
    } else {
      out << "VERTEX_SE3:QUAT " << k << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y()
          << ' ' << q.z() << ' ' << q.w() << '\n';
    }
  }
  for (const Factor& f : graph.factors) {
    if (f.kind == FactorKind::kPrior) {
      continue;  // g2o has no prior record; the reader anchors the first pose
    }
    const Eigen::Isometry3d& T = f.measurement;
    const Eigen::Vector3d t = T.translation();
    const Matrix6d& I = f.information;
    if (graph.dimension == 2) {
      out << "EDGE_SE2 " << f.a << ' ' << f.b << ' ' << t.x() << ' ' << t.y() << ' ' << std::atan2(T(1, 0), T(0, 0))
          << ' ' << I(0, 0) << ' ' << I(0, 1) << ' ' << I(0, 5) << ' ' << I(1, 1) << ' ' << I(1, 5) << ' ' << I(5, 5)
          << '\n';
    } else {
      const Eigen::Quaterniond q(T.rotation());
      out << "EDGE_SE3:QUAT " << f.a << ' ' << f.b << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x()
          << ' ' << q.y() << ' ' << q.z() << ' ' << q.w();
      for (int i = 0; i < 6; ++i) {
        for (int j = i; j < 6; ++j) {
          out << ' ' << I(i, j);
        }
      }
      out << '\n';
    }
  }
  if (!out) {
    throw G2oError(path + ": write failed");
  }
}

}  // namespace cdc::graph
