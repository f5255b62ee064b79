#include "cdc/odometry/global_registration.hpp"

#include "cdc/geometry/alignment.hpp"
#include "cdc/odometry/voxel_map.hpp"
#include "kdtree.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>

namespace cdc::odometry {
namespace {

using Feature = Eigen::Matrix<float, 33, 1>;
constexpr int kBins = 11;

int bin_of(double v, double lo, double hi) {
  const int b = static_cast<int>(std::floor((v - lo) / (hi - lo) * kBins));
  return std::clamp(b, 0, kBins - 1);
}

// The three angles of Rusu's Darboux frame between two oriented points; false when undefined.
bool pair_feature(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1, const Eigen::Vector3d& p2,
                  const Eigen::Vector3d& n2, double& f1, double& f2, double& f3) {
  Eigen::Vector3d d = p2 - p1;
  const double len = d.norm();
  if (len <= 0) return false;
  d /= len;
  const double a1 = n1.dot(d), a2 = n2.dot(d);
  // The frame sits at the point whose normal makes the smaller angle with the line between them.
  const bool swap = std::abs(a1) < std::abs(a2);
  const Eigen::Vector3d& u = swap ? n2 : n1;
  const Eigen::Vector3d& n_other = swap ? n1 : n2;
  if (swap) d = -d;
  f3 = swap ? -a2 : a1;
  Eigen::Vector3d v = d.cross(u);
  const double vn = v.norm();
  if (vn <= 1e-12) return false;
  v /= vn;
  const Eigen::Vector3d w = u.cross(v);
  f2 = v.dot(n_other);
  f1 = std::atan2(w.dot(n_other), u.dot(n_other));
  return true;
}

// Normals (PCA of the neighbours within the radius, turned towards the origin, where the sensor is).
std::vector<Eigen::Vector3d> normals_of(const std::vector<Eigen::Vector3d>& pts, const detail::KdTree& tree,
                                        double radius) {
  std::vector<Eigen::Vector3d> out(pts.size(), Eigen::Vector3d::Zero());
  std::vector<std::pair<size_t, double>> hits;
  std::vector<size_t> idx;
  for (size_t i = 0; i < pts.size(); ++i) {
    hits.clear();
    tree.radiusSearch(pts[i].data(), radius * radius, hits, nanoflann::SearchParams(32, 0, false));
    if (hits.size() < 5) continue;
    idx.clear();
    for (const auto& h : hits) idx.push_back(h.first);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(detail::neighbour_scatter(pts, idx.data(), idx.size()));
    const Eigen::Vector3d ev = es.eigenvalues();      // ascending
    if (ev(1) <= 0 || ev(0) > 0.3 * ev(1)) continue;  // no surface (scattered or a line)
    Eigen::Vector3d n = es.eigenvectors().col(0);
    if (n.dot(pts[i]) > 0) n = -n;
    out[i] = n;
  }
  return out;
}

}  // namespace

FeatureCloud make_feature_cloud(const std::vector<Eigen::Vector3d>& points_sensor, const GlobalRegistrationParams& p) {
  FeatureCloud c;
  c.points = voxel_centroids(points_sensor, p.voxel_m);
  const size_t n = c.points.size();
  c.features.assign(n, Feature::Zero());
  if (n < 5) {
    c.normals.assign(n, Eigen::Vector3d::Zero());
    return c;
  }
  const detail::CloudAdaptor adaptor{&c.points};
  const detail::KdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  c.normals = normals_of(c.points, tree, p.normal_radius_m);
  // Simplified point feature histograms (SPFH): each point with its neighbours within the support.
  std::vector<Feature> spfh(n, Feature::Zero());
  std::vector<std::vector<std::pair<size_t, double>>> neighbours(n);
  const double r2 = p.feature_radius_m * p.feature_radius_m;
  for (size_t i = 0; i < n; ++i) {
    if (c.normals[i].isZero()) continue;
    auto& hits = neighbours[i];
    tree.radiusSearch(c.points[i].data(), r2, hits, nanoflann::SearchParams(32, 0, false));
    int used = 0;
    for (const auto& [j, d2] : hits) {
      double f1 = 0, f2 = 0, f3 = 0;
      if (j == i || c.normals[j].isZero() ||
          !pair_feature(c.points[i], c.normals[i], c.points[j], c.normals[j], f1, f2, f3))
        continue;
      spfh[i](bin_of(f1, -M_PI, M_PI)) += 1.0F;
      spfh[i](kBins + bin_of(f2, -1.0, 1.0)) += 1.0F;
      spfh[i](2 * kBins + bin_of(f3, -1.0, 1.0)) += 1.0F;
      ++used;
    }
    if (used > 0) spfh[i] *= 100.0F / static_cast<float>(used);
  }
  // FPFH: a point's SPFH plus its neighbours' weighted by inverse distance, each histogram to 100.
  for (size_t i = 0; i < n; ++i) {
    if (spfh[i].isZero()) continue;
    Feature sum = Feature::Zero();
    for (const auto& [j, d2] : neighbours[i]) {
      if (j == i || spfh[j].isZero()) continue;
      sum += spfh[j] / static_cast<float>(std::sqrt(std::max(d2, 1e-6)));
    }
    for (int h = 0; h < 3; ++h) {
      const float s = sum.segment<kBins>(h * kBins).sum();
      if (s > 0) sum.segment<kBins>(h * kBins) *= 100.0F / s;
    }
    Feature f = spfh[i] + sum;
    for (int h = 0; h < 3; ++h) {
      const float s = f.segment<kBins>(h * kBins).sum();
      if (s > 0) f.segment<kBins>(h * kBins) *= 100.0F / s;
    }
    c.features[i] = f;
    c.with_feature.push_back(i);
  }
  return c;
}

namespace {

using Matches = std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>;  // (source, target)

// Mutual nearest neighbours in feature space, by blocks of a distance matrix (|a|^2 + |b|^2 - 2 a.b):
// exact, and faster than a k-d tree in 33 dimensions.
Matches mutual_matches(const FeatureCloud& src, const FeatureCloud& tgt) {
  const size_t ns = src.with_feature.size(), nt = tgt.with_feature.size();
  Eigen::MatrixXf A(33, static_cast<Eigen::Index>(ns)), B(33, static_cast<Eigen::Index>(nt));
  for (size_t i = 0; i < ns; ++i) A.col(static_cast<Eigen::Index>(i)) = src.features[src.with_feature[i]];
  for (size_t j = 0; j < nt; ++j) B.col(static_cast<Eigen::Index>(j)) = tgt.features[tgt.with_feature[j]];
  const Eigen::VectorXf a2 = A.colwise().squaredNorm().transpose(), b2 = B.colwise().squaredNorm().transpose();
  std::vector<Eigen::Index> best_t(ns, -1), best_s(nt, -1);
  std::vector<float> dist_t(ns, std::numeric_limits<float>::infinity());
  std::vector<float> dist_s(nt, std::numeric_limits<float>::infinity());
  constexpr Eigen::Index kBlock = 256;
  for (Eigen::Index i0 = 0; i0 < static_cast<Eigen::Index>(ns); i0 += kBlock) {
    const Eigen::Index m = std::min(kBlock, static_cast<Eigen::Index>(ns) - i0);
    const Eigen::MatrixXf dot = A.middleCols(i0, m).transpose() * B;  // m x nt
    for (Eigen::Index j = 0; j < static_cast<Eigen::Index>(nt); ++j) {
      for (Eigen::Index i = 0; i < m; ++i) {
        const float d = a2(i0 + i) + b2(j) - 2.0F * dot(i, j);
        const size_t si = static_cast<size_t>(i0 + i), tj = static_cast<size_t>(j);
        if (d < dist_t[si]) {
          dist_t[si] = d;
          best_t[si] = j;
        }
        if (d < dist_s[tj]) {
          dist_s[tj] = d;
          best_s[tj] = i0 + i;
        }
      }
    }
  }
  Matches matches;
  for (size_t i = 0; i < ns; ++i) {
    const Eigen::Index j = best_t[i];
    if (j < 0 || best_s[static_cast<size_t>(j)] != static_cast<Eigen::Index>(i)) continue;
    matches.emplace_back(src.points[src.with_feature[i]], tgt.points[tgt.with_feature[static_cast<size_t>(j)]]);
  }
  return matches;
}

// A transform and the number of matches within the inlier distance under it.
struct Consensus {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  int inliers = 0;
};

int count_inliers(const Matches& matches, const Eigen::Isometry3d& T, double inlier_m) {
  const double in2 = inlier_m * inlier_m;
  int c = 0;
  for (const auto& [s, t] : matches) c += (T * s - t).squaredNorm() < in2 ? 1 : 0;
  return c;
}

// RANSAC: three matches whose edges agree in length give a candidate; the one most matches agree
// with wins.
Consensus ransac(const Matches& matches, const GlobalRegistrationParams& p) {
  std::mt19937 rng(p.seed);
  std::uniform_int_distribution<size_t> pick(0, matches.size() - 1);
  auto edges_agree = [&](size_t a, size_t b) {
    const double ls = (matches[a].first - matches[b].first).norm(), lt = (matches[a].second - matches[b].second).norm();
    return std::min(ls, lt) >= p.edge_ratio * std::max(ls, lt) && ls > 2 * p.inlier_m;
  };
  Consensus best;
  Eigen::Matrix3Xd s3(3, 3), t3(3, 3);
  for (int it = 0; it < p.iterations; ++it) {
    const size_t a = pick(rng), b = pick(rng), c = pick(rng);
    if (a == b || b == c || a == c || !edges_agree(a, b) || !edges_agree(b, c) || !edges_agree(a, c)) continue;
    s3 << matches[a].first, matches[b].first, matches[c].first;
    t3 << matches[a].second, matches[b].second, matches[c].second;
    const geometry::Alignment al = geometry::align_umeyama(s3, t3, false);
    if (!al.ok) continue;
    const int n = count_inliers(matches, al.T_dst_src, p.inlier_m);
    if (n > best.inliers) best = {al.T_dst_src, n};
  }
  return best;
}

// Refits to all the inliers, twice (the refit can gather a few more), while the count does not drop.
void refit_to_inliers(const Matches& matches, double inlier_m, Consensus& best) {
  const double in2 = inlier_m * inlier_m;
  for (int round = 0; round < 2; ++round) {
    Eigen::Matrix3Xd s(3, best.inliers), t(3, best.inliers);
    Eigen::Index k = 0;
    for (const auto& [ps, pt] : matches) {
      if ((best.T * ps - pt).squaredNorm() >= in2 || k >= best.inliers) continue;
      s.col(k) = ps;
      t.col(k) = pt;
      ++k;
    }
    const geometry::Alignment al = geometry::align_umeyama(s.leftCols(k), t.leftCols(k), false);
    if (!al.ok) break;
    const int n = count_inliers(matches, al.T_dst_src, inlier_m);
    if (n < best.inliers) break;
    best = {al.T_dst_src, n};
  }
}

}  // namespace

GlobalRegistrationResult register_global(const FeatureCloud& src, const FeatureCloud& tgt,
                                         const GlobalRegistrationParams& p) {
  GlobalRegistrationResult out;
  if (src.with_feature.size() < 3 || tgt.with_feature.size() < 3) return out;
  const Matches matches = mutual_matches(src, tgt);
  out.matches = static_cast<int>(matches.size());
  if (matches.size() < 3) return out;
  Consensus best = ransac(matches, p);
  if (best.inliers < 3) return out;
  refit_to_inliers(matches, p.inlier_m, best);
  out.T_target_source = best.T;
  out.inliers = best.inliers;
  out.ok = true;
  return out;
}

}  // namespace cdc::odometry
