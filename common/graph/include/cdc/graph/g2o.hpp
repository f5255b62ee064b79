// g2o pose-graph files: 3D VERTEX_SE3:QUAT / EDGE_SE3:QUAT and 2D VERTEX_SE2 / EDGE_SE2 (lifted
// into 3D). Multi-robot files key poses as GTSAM symbols (('a' + robot) << 56 | index); they are
// read into cdc keys (robot << 56 | index).
#pragma once

#include "cdc/graph/pose_graph.hpp"

#include <stdexcept>
#include <string>
#include <vector>

namespace cdc::graph {

class G2oError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Information given to the out-of-plane directions (z, roll, pitch) of a lifted 2D edge.
inline constexpr double kPlanarLiftInformation = 1e6;

// What a read found about its vertices. A file may declare no vertex at all (manhattan, CSAIL): every pose
// is then initialised later and counted as implicit. A file that declares vertices must declare every vertex its
// edges name, and each id once (again only with the same pose); otherwise the read fails.
struct G2oReadReport {
  size_t vertices = 0;              // distinct ids declared by VERTEX lines
  size_t implicit_vertices = 0;     // ids only edges name (files without VERTEX lines)
  size_t conflicting_vertices = 0;  // ids several files of a folder declare with different poses: the first kept
  // Folders: edges a later file lists again with the same ends, measurement and information (an
  // inter-robot edge both robots list), kept once.
  size_t duplicate_edges = 0;
  // Edges whose two poses an earlier edge already links with another measurement (or in the same
  // file): each is kept as a factor of its own.
  size_t parallel_edges = 0;
  size_t skipped_lines = 0;  // lines skipped as malformed (G2oReadOptions::skip_malformed)
  // Edges whose information is not positive definite, read for their isotropic weights
  // (G2oReadOptions::isotropic_information): the full-information cost means nothing for them.
  size_t indefinite_information = 0;
};

struct G2oReadOptions {
  // Skip lines that cannot be parsed instead of failing; each skipped line is reported in warnings
  // ("file:line: reason"). For external data with damaged lines.
  bool skip_malformed = false;
  std::vector<std::string>* warnings = nullptr;
  G2oReadReport* report = nullptr;  // filled when set
  // Accept an edge whose information is not positive definite as long as the isotropic weights of
  // SE-Sync's objective (tau, kappa; objective.hpp) are positive: for solves of that objective,
  // which uses nothing else of the information.
  bool isotropic_information = false;
};

// Reads a file; poses without a VERTEX line are initialised later (see chordal_initialise or
// initialise_from_odometry). Throws G2oError naming file and line.
PoseGraph read_g2o(const std::string& path, const G2oReadOptions& options = {});

// Reads every *.g2o file of a folder into one graph, one file per robot: every id must carry its robot
// letter (GTSAM symbols), else the read fails. An edge two files list alike is kept once; parallel
// edges (same two poses, another measurement) are all kept.
PoseGraph read_g2o_folder(const std::string& folder, const G2oReadOptions& options = {});

// The id a key had in a g2o file: GTSAM symbols when the graph was read from them.
uint64_t to_g2o_key(const PoseGraph& graph, Key key);

// Writes 3D (or SE2 lines when graph.dimension == 2). Keys are written as cdc keys.
void write_g2o(const std::string& path, const PoseGraph& graph);

// GTSAM symbol key ('a' + robot) << 56 | index -> cdc key; plain keys pass unchanged.
Key from_g2o_key(uint64_t raw);

}  // namespace cdc::graph
