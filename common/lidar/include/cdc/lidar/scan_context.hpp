// Scan Context (Kim & Kim, IROS 2018): a rotation-invariant place descriptor of a LiDAR scan.
// A polar grid (rings x sectors) around the sensor holds the highest point of each cell; the
// ring key (mean of each ring) is invariant to yaw and serves for retrieval; comparing two
// descriptors over all column shifts gives their distance and the yaw between the scans.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <vector>

namespace cdc::lidar {

struct ScanContextParams {
  int rings = 20;
  int sectors = 60;
  double max_range_m = 80.0;
  double sensor_height_m = 2.0;  // added to z so that cell heights are positive
};

struct ScanContext {
  int rings = 0, sectors = 0;
  std::vector<float> cells;     // rings x sectors, row-major (ring, sector); height [m] (0: empty)
  std::vector<float> ring_key;  // rings
  float at(int r, int s) const { return cells[static_cast<size_t>(r * sectors + s)]; }
};

ScanContext make_scan_context(const std::vector<Eigen::Vector3f>& points, const ScanContextParams& p);

// The descriptor of the same points seen from a virtual sensor at `sensor` (in the points' frame,
// same orientation): a place revisited a lane or two aside (driving the other way, on the opposite
// lane) has its polar grid centred elsewhere, and its Scan Context differs from the original's far
// more than a rotation does; the view from beside it matches (Scan Context++'s lateral augmentation).
ScanContext make_scan_context(const std::vector<Eigen::Vector3f>& points, const ScanContextParams& p,
                              const Eigen::Vector3f& sensor);

// Sets sc.ring_key from its cells: each ring's mean height (rotation invariant).
void compute_ring_key(ScanContext& sc);

struct ScanContextMatch {
  double distance = 1.0;  // 0 identical .. 1 unrelated (mean column cosine distance)
  int shift = 0;          // columns: query column c matches candidate column (c + shift) mod sectors
  double yaw_rad = 0.0;   // rotation of the query scan relative to the candidate's
};

ScanContextMatch compare(const ScanContext& query, const ScanContext& candidate);

// Quantised form for the wire: one byte per cell holding the square root of the cell height in
// steps of `scale` (height = (byte * scale)^2), the step chosen per descriptor so that its highest
// cell is 255; occupied cells never become empty. The ring key does not travel: dequantize computes
// it from the cells, so that every robot's database holds the same key for a descriptor.
struct QuantizedScanContext {
  int rings = 0, sectors = 0;
  float scale = 0.02f;  // [sqrt(m)] per step
  std::vector<uint8_t> cells;
  size_t bytes() const { return cells.size() + 3 * sizeof(float); }
};
QuantizedScanContext quantize(const ScanContext& sc);
ScanContext dequantize(const QuantizedScanContext& q);

// Retrieval: nearest ring keys (nanoflann k-d tree), then Scan Context distance of the best.
class ScanContextDatabase {
 public:
  explicit ScanContextDatabase(int rings);
  ~ScanContextDatabase();
  size_t add(ScanContext sc);  // returns its id (0, 1, ...)
  size_t size() const noexcept { return contexts_.size(); }
  const ScanContext& at(size_t id) const { return contexts_[id]; }

  struct Candidate {
    size_t id;
    ScanContextMatch match;
  };
  // The `knn` nearest ring keys among ids for which `allowed(id)` is true, sorted by Scan Context
  // distance (best first).
  template <class Allowed>
  std::vector<Candidate> query(const ScanContext& q, size_t knn, Allowed allowed) const;

 private:
  std::vector<size_t> nearest(const std::vector<float>& key, size_t k) const;
  int rings_;
  std::vector<ScanContext> contexts_;
  struct Index;
  std::unique_ptr<Index> index_;
};

template <class Allowed>
std::vector<ScanContextDatabase::Candidate> ScanContextDatabase::query(const ScanContext& q, size_t knn,
                                                                       Allowed allowed) const {
  std::vector<Candidate> out;
  // Ask for extra neighbours so that excluded ids do not starve the result.
  for (size_t id : nearest(q.ring_key, std::min(contexts_.size(), knn * 4 + 16))) {
    if (!allowed(id)) continue;
    out.push_back({id, compare(q, contexts_[id])});
    if (out.size() >= knn) break;
  }
  std::sort(out.begin(), out.end(),
            [](const Candidate& a, const Candidate& b) { return a.match.distance < b.match.distance; });
  return out;
}

}  // namespace cdc::lidar
