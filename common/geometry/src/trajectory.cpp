#include "cdc/geometry/trajectory.hpp"

#include "cdc/geometry/se3.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>

namespace cdc::geometry {
namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) {
    return {};
  }
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

std::vector<std::string> split_ws(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  std::string tok;
  while (in >> tok) {
    out.push_back(tok);
  }
  return out;
}

bool parse_double(const std::string& tok, double& v) {
  const char* b = tok.data();
  const char* e = tok.data() + tok.size();
  auto [ptr, ec] = std::from_chars(b, e, v);
  return ec == std::errc() && ptr == e && std::isfinite(v);
}

std::ifstream open_or_throw(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    throw TrajectoryFileError(path, 0, "cannot open file");
  }
  return in;
}

// The non-empty, non-comment lines of a file, split into columns, with their line numbers.
class DataLines {
 public:
  explicit DataLines(const std::string& path) : in_(open_or_throw(path)) {}

  // The next data line's number and columns; false at the end of the file.
  bool next(size_t& number, std::vector<std::string>& columns) {
    std::string line;
    while (std::getline(in_, line)) {
      ++n_;
      const std::string t = trim(line);
      if (t.empty() || t[0] == '#') {
        continue;
      }
      number = n_;
      columns = split_ws(t);
      return true;
    }
    return false;
  }

 private:
  std::ifstream in_;
  size_t n_ = 0;
};

// Calls f(line_number, columns) for every non-empty, non-comment line.
template <class F>
void for_each_data_line(const std::string& path, F&& f) {
  DataLines lines(path);
  size_t n = 0;
  std::vector<std::string> cols;
  while (lines.next(n, cols)) {
    f(n, cols);
  }
}

std::ofstream create_or_throw(const std::string& path) {
  std::ofstream out(path);
  if (!out) {
    throw TrajectoryFileError(path, 0, "cannot create file");
  }
  out << std::setprecision(9);
  return out;
}

Eigen::Isometry3d pose_from_rt(const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const std::string& path,
                               size_t line) {
  // Files written with limited precision carry slightly non-orthonormal rotations; project them
  // back, but refuse matrices that are not rotations at all.
  const double err = (R * R.transpose() - Eigen::Matrix3d::Identity()).norm();
  if (err > 1e-2 || R.determinant() < 0.0) {
    throw TrajectoryFileError(path, line,
                              "rotation block is not a rotation matrix (|R R^T - I| = " + std::to_string(err) + ")");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = project_to_so3(R);
  T.translation() = t;
  return T;
}

}  // namespace

namespace {
// "path:line: message" (no line when 0). Appended piece by piece: GCC 12's release build warns
// (-Wrestrict, a false positive) on `":" + std::to_string(line)`.
std::string where_what(const std::string& path, size_t line, const std::string& message) {
  std::string s = path;
  if (line > 0) s.append(":").append(std::to_string(line));
  return s.append(": ").append(message);
}
}  // namespace

TrajectoryFileError::TrajectoryFileError(const std::string& path, size_t line, const std::string& message)
    : std::runtime_error(where_what(path, line, message)), path_(path), line_(line) {}

std::optional<int64_t> parse_seconds_ns(const std::string& text) {
  const std::string t = trim(text);
  if (t.empty()) {
    return std::nullopt;
  }
  // Plain decimal "123.456789": integer and fraction separately, exact to the nanosecond.
  const bool plain =
      t.find_first_not_of("0123456789.-+") == std::string::npos && std::count(t.begin(), t.end(), '.') <= 1;
  if (plain) {
    bool neg = t[0] == '-';
    std::string body = (t[0] == '-' || t[0] == '+') ? t.substr(1) : t;
    if (body.empty() || body.find_first_of("+-") != std::string::npos) {
      return std::nullopt;
    }
    const auto dot = body.find('.');
    const std::string ip = body.substr(0, dot);
    std::string fp = dot == std::string::npos ? std::string() : body.substr(dot + 1);
    if (ip.empty() && fp.empty()) {
      return std::nullopt;
    }
    // Nanoseconds in int64 reach 9223372036.854775807 s (the year 2262): a stamp beyond is refused.
    constexpr int64_t kMaxSeconds = (std::numeric_limits<int64_t>::max() - 999'999'999) / 1'000'000'000;
    if (ip.size() > 10) {
      return std::nullopt;
    }
    const int64_t sec = ip.empty() ? 0 : std::stoll(ip);
    if (sec > kMaxSeconds) {
      return std::nullopt;
    }
    fp.resize(9, '0');  // truncate below 1 ns
    const int64_t ns = std::stoll(fp.substr(0, 9));
    const int64_t v = sec * 1'000'000'000 + ns;
    return neg ? -v : v;
  }
  char* end = nullptr;
  const long double v = std::strtold(t.c_str(), &end);
  if (end == t.c_str() || *end != '\0' || !std::isfinite(static_cast<double>(v)) || std::fabs(v) > 9.2e9L) {
    return std::nullopt;
  }
  return static_cast<int64_t>(std::llroundl(v * 1e9L));
}

Trajectory read_tum(const std::string& path) {
  Trajectory traj;
  for_each_data_line(path, [&](size_t line, const std::vector<std::string>& cols) {
    if (cols.size() != 8) {
      throw TrajectoryFileError(path, line,
                                "expected 8 columns (t x y z qx qy qz qw), found " + std::to_string(cols.size()));
    }
    const auto stamp = parse_seconds_ns(cols[0]);
    if (!stamp) {
      throw TrajectoryFileError(path, line, "bad time stamp '" + cols[0] + "'");
    }
    double v[7];
    for (int i = 0; i < 7; ++i) {
      if (!parse_double(cols[static_cast<size_t>(i) + 1], v[i])) {
        throw TrajectoryFileError(
            path, line,
            "column " + std::to_string(i + 2) + ": '" + cols[static_cast<size_t>(i) + 1] + "' is not a finite number");
      }
    }
    const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (std::abs(q.norm() - 1.0) > 1e-2) {
      throw TrajectoryFileError(path, line, "quaternion norm " + std::to_string(q.norm()) + " is not 1");
    }
    if (!traj.empty() && *stamp <= traj.back().stamp_ns) {
      throw TrajectoryFileError(path, line, "time stamp " + cols[0] + " does not increase");
    }
    traj.push_back({*stamp, make_pose({v[0], v[1], v[2]}, q)});
  });
  return traj;
}

void write_tum(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = create_or_throw(path);
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (const auto& sp : trajectory) {
    const Eigen::Quaterniond q(sp.pose.rotation());
    const int64_t mag = sp.stamp_ns < 0 ? -sp.stamp_ns : sp.stamp_ns;
    char stamp[48];
    std::snprintf(stamp, sizeof stamp, "%s%lld.%09lld", sp.stamp_ns < 0 ? "-" : "",
                  static_cast<long long>(mag / 1'000'000'000), static_cast<long long>(mag % 1'000'000'000));
    const Eigen::Vector3d t = sp.pose.translation();
    out << stamp << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' '
        << q.w() << '\n';
  }
  if (!out) {
    throw TrajectoryFileError(path, 0, "write failed");
  }
}

Trajectory read_kitti(const std::string& path, const std::vector<int64_t>* stamps_ns, int64_t period_ns) {
  Trajectory traj;
  for_each_data_line(path, [&](size_t line, const std::vector<std::string>& cols) {
    if (cols.size() != 12) {
      throw TrajectoryFileError(path, line,
                                "expected 12 columns (3x4 row-major [R|t]), found " + std::to_string(cols.size()));
    }
    double v[12];
    for (size_t i = 0; i < 12; ++i) {
      if (!parse_double(cols[i], v[i])) {
        throw TrajectoryFileError(path, line,
                                  "column " + std::to_string(i + 1) + ": '" + cols[i] + "' is not a finite number");
      }
    }
    Eigen::Matrix3d R;
    R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    const Eigen::Vector3d t(v[3], v[7], v[11]);
    const size_t index = traj.size();
    int64_t stamp = static_cast<int64_t>(index) * period_ns;
    if (stamps_ns != nullptr) {
      if (index >= stamps_ns->size()) {
        throw TrajectoryFileError(path, line,
                                  "more poses than time stamps (" + std::to_string(stamps_ns->size()) + ")");
      }
      stamp = (*stamps_ns)[index];
    }
    traj.push_back({stamp, pose_from_rt(R, t, path, line)});
  });
  if (stamps_ns != nullptr && stamps_ns->size() != traj.size()) {
    throw TrajectoryFileError(
        path, 0, std::to_string(traj.size()) + " poses but " + std::to_string(stamps_ns->size()) + " time stamps");
  }
  return traj;
}

void write_kitti(const std::string& path, const Trajectory& trajectory) {
  std::ofstream out = create_or_throw(path);
  for (const auto& sp : trajectory) {
    const Eigen::Matrix<double, 3, 4> M = sp.pose.matrix().topRows<3>();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        out << M(r, c) << ((r == 2 && c == 3) ? '\n' : ' ');
      }
    }
  }
  if (!out) {
    throw TrajectoryFileError(path, 0, "write failed");
  }
}

std::vector<int64_t> read_times(const std::string& path) {
  std::vector<int64_t> out;
  for_each_data_line(path, [&](size_t line, const std::vector<std::string>& cols) {
    if (cols.size() != 1) {
      throw TrajectoryFileError(path, line,
                                "expected one time in seconds, found " + std::to_string(cols.size()) + " columns");
    }
    const auto ns = parse_seconds_ns(cols[0]);
    if (!ns) {
      throw TrajectoryFileError(path, line, "bad time '" + cols[0] + "'");
    }
    if (!out.empty() && *ns <= out.back()) {
      throw TrajectoryFileError(path, line, "time " + cols[0] + " does not increase");
    }
    out.push_back(*ns);
  });
  return out;
}

TrajectoryFormat detect_format(const std::string& path) {
  DataLines lines(path);
  size_t n = 0;
  std::vector<std::string> columns;
  if (!lines.next(n, columns)) {
    throw TrajectoryFileError(path, 0, "no poses in file");
  }
  const size_t cols = columns.size();
  if (cols == 8) {
    return TrajectoryFormat::kTum;
  }
  if (cols == 12) {
    return TrajectoryFormat::kKitti;
  }
  throw TrajectoryFileError(path, n,
                            "cannot tell the format: " + std::to_string(cols) + " columns (TUM has 8, KITTI 12)");
}

std::optional<TrajectoryFormat> parse_format(const std::string& name) {
  if (name == "tum") {
    return TrajectoryFormat::kTum;
  }
  if (name == "kitti") {
    return TrajectoryFormat::kKitti;
  }
  return std::nullopt;
}

std::optional<Eigen::Isometry3d> interpolate_at(const Trajectory& trajectory, int64_t stamp_ns) {
  if (trajectory.empty() || stamp_ns < trajectory.front().stamp_ns || stamp_ns > trajectory.back().stamp_ns) {
    return std::nullopt;
  }
  auto it = std::lower_bound(trajectory.begin(), trajectory.end(), stamp_ns,
                             [](const StampedPose& p, int64_t s) { return p.stamp_ns < s; });
  if (it->stamp_ns == stamp_ns) {
    return it->pose;
  }
  const StampedPose& b = *it;
  const StampedPose& a = *(it - 1);
  const double t = static_cast<double>(stamp_ns - a.stamp_ns) / static_cast<double>(b.stamp_ns - a.stamp_ns);
  return interpolate(a.pose, b.pose, t);
}

std::vector<std::pair<size_t, size_t>> associate(const Trajectory& a, const Trajectory& b, int64_t max_dt_ns) {
  std::vector<std::pair<size_t, size_t>> out;
  if (b.empty()) {
    return out;
  }
  size_t last_j = 0;
  bool have_last = false;
  for (size_t i = 0; i < a.size(); ++i) {
    const int64_t s = a[i].stamp_ns;
    auto it = std::lower_bound(b.begin(), b.end(), s, [](const StampedPose& p, int64_t v) { return p.stamp_ns < v; });
    size_t best = b.size();
    int64_t best_dt = max_dt_ns + 1;
    for (auto c : {it, it == b.begin() ? b.end() : it - 1}) {
      if (c == b.end()) {
        continue;
      }
      const int64_t dt = std::llabs(c->stamp_ns - s);
      if (dt < best_dt) {
        best_dt = dt;
        best = static_cast<size_t>(c - b.begin());
      }
    }
    if (best == b.size() || best_dt > max_dt_ns || (have_last && best <= last_j)) {
      continue;
    }
    out.emplace_back(i, best);
    last_j = best;
    have_last = true;
  }
  return out;
}

double path_length(const Trajectory& trajectory) {
  double len = 0.0;
  for (size_t i = 1; i < trajectory.size(); ++i) {
    len += (trajectory[i].pose.translation() - trajectory[i - 1].pose.translation()).norm();
  }
  return len;
}

}  // namespace cdc::geometry
