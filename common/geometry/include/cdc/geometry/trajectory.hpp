// Stamped trajectories and their files: TUM ("t x y z qx qy qz qw") and KITTI (3x4 row-major).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace cdc::geometry {

struct StampedPose {
  int64_t stamp_ns = 0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

using Trajectory = std::vector<StampedPose>;

enum class TrajectoryFormat { kTum, kKitti };

// A file that cannot be read or parsed; what() names the file and line.
class TrajectoryFileError : public std::runtime_error {
 public:
  TrajectoryFileError(const std::string& path, size_t line, const std::string& message);
  const std::string& path() const noexcept { return path_; }
  size_t line() const noexcept { return line_; }

 private:
  std::string path_;
  size_t line_;
};

// TUM: "stamp[s] x y z qx qy qz qw" per line, '#' comments. Stamps must increase.
Trajectory read_tum(const std::string& path);
void write_tum(const std::string& path, const Trajectory& trajectory);

// KITTI: 12 numbers per line (3x4 row-major [R|t]). Stamps come from `stamps_ns` when given
// (one per line), else pose i gets stamp i * period_ns.
Trajectory read_kitti(const std::string& path, const std::vector<int64_t>* stamps_ns = nullptr,
                      int64_t period_ns = 100'000'000);
void write_kitti(const std::string& path, const Trajectory& trajectory);

// A KITTI times file: one time in seconds per line, returned in nanoseconds.
std::vector<int64_t> read_times(const std::string& path);

// By the first data line: 8 columns -> TUM, 12 -> KITTI. Throws when neither.
TrajectoryFormat detect_format(const std::string& path);
std::optional<TrajectoryFormat> parse_format(const std::string& name);  // "tum", "kitti"

// Seconds as text ("1.5") to nanoseconds, without going through a double's rounding.
std::optional<int64_t> parse_seconds_ns(const std::string& text);

// Pose at `stamp_ns` interpolated between the two neighbouring samples; nullopt outside the
// trajectory's time span. The trajectory must be sorted by stamp.
std::optional<Eigen::Isometry3d> interpolate_at(const Trajectory& trajectory, int64_t stamp_ns);

// Pairs (index in a, index in b) of samples whose stamps differ by at most max_dt_ns, each
// sample used at most once, nearest first. Both trajectories sorted by stamp.
std::vector<std::pair<size_t, size_t>> associate(const Trajectory& a, const Trajectory& b, int64_t max_dt_ns);

// Sum of distances between consecutive positions [m].
double path_length(const Trajectory& trajectory);

}  // namespace cdc::geometry
