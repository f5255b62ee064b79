#include "cdc/geometry/metrics.hpp"

#include "cdc/base/names.hpp"
#include "cdc/geometry/se3.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

namespace cdc::geometry {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

constexpr std::array<base::Named<AlignMode>, 3> kAlignModeNames{
    {{AlignMode::kNone, "none"}, {AlignMode::kSE3, "se3"}, {AlignMode::kSim3, "sim3"}}};

Eigen::Matrix3Xd positions(const Poses& poses) {
  Eigen::Matrix3Xd m(3, static_cast<Eigen::Index>(poses.size()));
  for (size_t i = 0; i < poses.size(); ++i) {
    m.col(static_cast<Eigen::Index>(i)) = poses[i].translation();
  }
  return m;
}

// Relative error of the pair (i, j).
Eigen::Isometry3d relative_error(const Poses& est, const Poses& gt, size_t i, size_t j) {
  const Eigen::Isometry3d d_gt = gt[i].inverse() * gt[j];
  const Eigen::Isometry3d d_est = est[i].inverse() * est[j];
  return d_gt.inverse() * d_est;
}

RpeResult rpe_from_pairs(const Poses& est, const Poses& gt, const std::vector<std::pair<size_t, size_t>>& pairs,
                         std::string delta) {
  std::vector<double> t, r;
  t.reserve(pairs.size());
  r.reserve(pairs.size());
  for (auto [i, j] : pairs) {
    const Eigen::Isometry3d E = relative_error(est, gt, i, j);
    t.push_back(E.translation().norm());
    r.push_back(rotation_angle(E.rotation()) * kRadToDeg);
  }
  RpeResult out;
  out.translation = compute_stats(std::move(t));
  out.rotation_deg = compute_stats(std::move(r));
  out.delta = std::move(delta);
  return out;
}

// Cumulative ground-truth path distance at each pose [m].
std::vector<double> cumulative_distance(const Poses& gt) {
  std::vector<double> d(gt.size(), 0.0);
  for (size_t i = 1; i < gt.size(); ++i) {
    d[i] = d[i - 1] + (gt[i].translation() - gt[i - 1].translation()).norm();
  }
  return d;
}

// First index j > i with dist[j] >= dist[i] + length, or dist.size() when none.
size_t first_frame_after(const std::vector<double>& dist, size_t i, double length) {
  auto it = std::lower_bound(dist.begin() + static_cast<std::ptrdiff_t>(i), dist.end(), dist[i] + length);
  return static_cast<size_t>(it - dist.begin());
}

}  // namespace

std::optional<AlignMode> parse_align_mode(const std::string& name) { return base::value_of(kAlignModeNames, name); }

const char* to_string(AlignMode mode) { return base::name_of(kAlignModeNames, mode, "?"); }

ErrorStats compute_stats(std::vector<double> values) {
  ErrorStats s;
  s.count = values.size();
  if (values.empty()) {
    return s;
  }
  const double n = static_cast<double>(values.size());
  double sum = 0.0, sq = 0.0;
  for (double v : values) {
    sum += v;
    sq += v * v;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sq / n);
  s.std = std::sqrt(std::max(0.0, sq / n - s.mean * s.mean));
  std::sort(values.begin(), values.end());
  s.min = values.front();
  s.max = values.back();
  const size_t mid = values.size() / 2;
  s.median = values.size() % 2 == 1 ? values[mid] : 0.5 * (values[mid - 1] + values[mid]);
  s.p90 = values[static_cast<size_t>(std::lround(0.9 * static_cast<double>(values.size() - 1)))];
  return s;
}

AteResult compute_ate(const Poses& est, const Poses& gt, AlignMode mode) {
  AteResult out;
  const size_t n = std::min(est.size(), gt.size());
  if (n == 0) {
    return out;
  }
  if (mode == AlignMode::kNone) {
    out.alignment.ok = true;
  } else {
    out.alignment = align_umeyama(positions(est), positions(gt), mode == AlignMode::kSim3);
  }
  std::vector<double> t(n), r(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Isometry3d e = apply(out.alignment, est[i]);
    t[i] = (e.translation() - gt[i].translation()).norm();
    r[i] = rotation_angle(gt[i].rotation().transpose() * e.rotation()) * kRadToDeg;
  }
  out.translation = compute_stats(std::move(t));
  out.rotation_deg = compute_stats(std::move(r));
  return out;
}

RpeResult compute_rpe_frames(const Poses& est, const Poses& gt, size_t delta_frames) {
  std::vector<std::pair<size_t, size_t>> pairs;
  const size_t n = std::min(est.size(), gt.size());
  for (size_t i = 0; delta_frames > 0 && i + delta_frames < n; ++i) {
    pairs.emplace_back(i, i + delta_frames);
  }
  return rpe_from_pairs(est, gt, pairs, std::to_string(delta_frames) + (delta_frames == 1 ? " frame" : " frames"));
}

RpeResult compute_rpe_distance(const Poses& est, const Poses& gt, double delta_m) {
  const size_t n = std::min(est.size(), gt.size());
  const Poses g(gt.begin(), gt.begin() + static_cast<std::ptrdiff_t>(n));
  const std::vector<double> dist = cumulative_distance(g);
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t i = 0; i < n && delta_m > 0.0; ++i) {
    const size_t j = first_frame_after(dist, i, delta_m);
    if (j >= n) {
      break;
    }
    pairs.emplace_back(i, j);
  }
  char label[32];
  std::snprintf(label, sizeof label, "%g m", delta_m);
  return rpe_from_pairs(est, gt, pairs, label);
}

KittiDrift compute_kitti_drift(const Poses& est, const Poses& gt, size_t step_frames) {
  static constexpr std::array<double, 8> kLengths = {100, 200, 300, 400, 500, 600, 700, 800};
  const size_t n = std::min(est.size(), gt.size());
  const Poses g(gt.begin(), gt.begin() + static_cast<std::ptrdiff_t>(n));
  const std::vector<double> dist = cumulative_distance(g);
  double t_sum = 0.0, r_sum = 0.0;
  size_t count = 0;
  for (size_t first = 0; first < n; first += std::max<size_t>(step_frames, 1)) {
    for (double len : kLengths) {
      const size_t last = first_frame_after(dist, first, len);
      if (last >= n) {
        continue;
      }
      const Eigen::Isometry3d E = relative_error(est, gt, first, last);
      t_sum += E.translation().norm() / len;
      r_sum += rotation_angle(E.rotation()) / len;
      ++count;
    }
  }
  KittiDrift out;
  out.segments = count;
  if (count > 0) {
    out.translation_pct = 100.0 * t_sum / static_cast<double>(count);
    out.rotation_deg_per_100m = 100.0 * kRadToDeg * r_sum / static_cast<double>(count);
  }
  return out;
}

}  // namespace cdc::geometry
