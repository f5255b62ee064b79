#include "cdc/lidar/scan_context.hpp"

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>

namespace cdc::lidar {

ScanContext make_scan_context(const std::vector<Eigen::Vector3f>& points, const ScanContextParams& p) {
  return make_scan_context(points, p, Eigen::Vector3f::Zero());
}

ScanContext make_scan_context(const std::vector<Eigen::Vector3f>& points, const ScanContextParams& p,
                              const Eigen::Vector3f& sensor) {
  ScanContext sc;
  sc.rings = p.rings;
  sc.sectors = p.sectors;
  sc.cells.assign(static_cast<size_t>(p.rings * p.sectors), 0.0f);
  for (const Eigen::Vector3f& seen : points) {
    const Eigen::Vector3f pt = seen - sensor;
    const double r = std::hypot(pt.x(), pt.y());
    if (r <= 0.0 || r >= p.max_range_m || !std::isfinite(r)) continue;
    double az = std::atan2(pt.y(), pt.x());  // (-pi, pi]
    if (az < 0) az += 2 * M_PI;
    const int ring = std::min(p.rings - 1, static_cast<int>(r / p.max_range_m * p.rings));
    const int sector = std::min(p.sectors - 1, static_cast<int>(az / (2 * M_PI) * p.sectors));
    const float h = static_cast<float>(std::max(0.0, pt.z() + p.sensor_height_m));
    float& cell = sc.cells[static_cast<size_t>(ring * p.sectors + sector)];
    cell = std::max(cell, h);
  }
  compute_ring_key(sc);
  return sc;
}

void compute_ring_key(ScanContext& sc) {
  sc.ring_key.assign(static_cast<size_t>(sc.rings), 0.0f);
  for (int r = 0; r < sc.rings; ++r) {
    double sum = 0;
    for (int s = 0; s < sc.sectors; ++s) sum += sc.at(r, s);
    sc.ring_key[static_cast<size_t>(r)] = static_cast<float>(sum / sc.sectors);
  }
}

ScanContextMatch compare(const ScanContext& q, const ScanContext& c) {
  ScanContextMatch best;
  if (q.rings != c.rings || q.sectors != c.sectors) return best;
  const int S = q.sectors;
  // Column norms once.
  std::vector<double> nq(static_cast<size_t>(S)), nc(static_cast<size_t>(S));
  for (int s = 0; s < S; ++s) {
    double a = 0, b = 0;
    for (int r = 0; r < q.rings; ++r) {
      a += static_cast<double>(q.at(r, s)) * q.at(r, s);
      b += static_cast<double>(c.at(r, s)) * c.at(r, s);
    }
    nq[static_cast<size_t>(s)] = std::sqrt(a);
    nc[static_cast<size_t>(s)] = std::sqrt(b);
  }
  for (int shift = 0; shift < S; ++shift) {
    double sim = 0;
    int n = 0;
    for (int s = 0; s < S; ++s) {
      const int t = (s + shift) % S;
      if (nq[static_cast<size_t>(s)] == 0 || nc[static_cast<size_t>(t)] == 0) continue;
      double dot = 0;
      for (int r = 0; r < q.rings; ++r) dot += static_cast<double>(q.at(r, s)) * c.at(r, t);
      sim += dot / (nq[static_cast<size_t>(s)] * nc[static_cast<size_t>(t)]);
      ++n;
    }
    const double d = n == 0 ? 1.0 : 1.0 - sim / n;
    if (d < best.distance) {
      best.distance = d;
      best.shift = shift;
    }
  }
  // Query column s sees what the candidate saw at column s + shift: the query is rotated by
  // -shift sectors relative to the candidate.
  double yaw = -2 * M_PI * best.shift / S;
  if (yaw <= -M_PI) yaw += 2 * M_PI;
  best.yaw_rad = yaw;
  return best;
}

QuantizedScanContext quantize(const ScanContext& sc) {
  QuantizedScanContext q;
  float top = 0;
  for (float c : sc.cells) top = std::max(top, std::sqrt(std::max(c, 0.0f)));
  const float scale = std::max(top / 255.0f, 1e-4f);
  q.rings = sc.rings;
  q.sectors = sc.sectors;
  q.scale = scale;
  q.cells.resize(sc.cells.size());
  for (size_t i = 0; i < sc.cells.size(); ++i) {
    // Square-root steps: fine for the low cells (ground, cars) that dominate most columns. An
    // occupied cell stays occupied (at least one step): an empty column compares differently.
    const long lo = sc.cells[i] > 0.0f ? 1L : 0L;
    q.cells[i] =
        static_cast<uint8_t>(std::clamp(std::lround(std::sqrt(std::max(sc.cells[i], 0.0f)) / scale), lo, 255L));
  }
  return q;
}

ScanContext dequantize(const QuantizedScanContext& q) {
  ScanContext sc;
  sc.rings = q.rings;
  sc.sectors = q.sectors;
  sc.cells.resize(q.cells.size());
  for (size_t i = 0; i < q.cells.size(); ++i) {
    const float r = static_cast<float>(q.cells[i]) * q.scale;
    sc.cells[i] = r * r;
  }
  compute_ring_key(sc);
  return sc;
}

// nanoflann adaptor over the ring keys; rebuilt lazily when contexts were added.
struct ScanContextDatabase::Index {
  struct Adaptor {
    const std::vector<ScanContext>* contexts;
    size_t kdtree_get_point_count() const { return contexts->size(); }
    float kdtree_get_pt(size_t idx, size_t dim) const { return (*contexts)[idx].ring_key[dim]; }
    template <class BBox>
    bool kdtree_get_bbox(BBox&) const {
      return false;
    }
  };
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Adaptor>, Adaptor, -1, size_t>;
  Adaptor adaptor;
  std::unique_ptr<Tree> tree;
  size_t built_for = 0;
};

ScanContextDatabase::ScanContextDatabase(int rings) : rings_(rings), index_(std::make_unique<Index>()) {
  index_->adaptor.contexts = &contexts_;
}
ScanContextDatabase::~ScanContextDatabase() = default;

size_t ScanContextDatabase::add(ScanContext sc) {
  contexts_.push_back(std::move(sc));
  return contexts_.size() - 1;
}

std::vector<size_t> ScanContextDatabase::nearest(const std::vector<float>& key, size_t k) const {
  std::vector<size_t> out;
  if (contexts_.empty() || k == 0) return out;
  // Rebuild when the database grew by more than 10 % (a query between rebuilds also scans the
  // newest contexts linearly, so nothing added is ever missed).
  if (!index_->tree || contexts_.size() > index_->built_for + index_->built_for / 10 + 10) {
    // nanoflann builds the index in the tree's constructor.
    index_->tree =
        std::make_unique<Index::Tree>(rings_, index_->adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    index_->built_for = contexts_.size();
  }
  std::vector<std::pair<float, size_t>> cand;
  const size_t kk = std::min(k, index_->built_for);
  if (kk > 0) {
    std::vector<size_t> ids(kk);
    std::vector<float> d2(kk);
    nanoflann::KNNResultSet<float, size_t> rs(kk);
    rs.init(ids.data(), d2.data());
    index_->tree->findNeighbors(rs, key.data(), nanoflann::SearchParams());
    for (size_t i = 0; i < rs.size(); ++i) cand.emplace_back(d2[i], ids[i]);
  }
  for (size_t id = index_->built_for; id < contexts_.size(); ++id) {
    float d = 0;
    for (size_t r = 0; r < key.size(); ++r) {
      const float e = key[r] - contexts_[id].ring_key[r];
      d += e * e;
    }
    cand.emplace_back(d, id);
  }
  std::sort(cand.begin(), cand.end());
  for (size_t i = 0; i < cand.size() && i < k; ++i) out.push_back(cand[i].second);
  return out;
}

}  // namespace cdc::lidar
