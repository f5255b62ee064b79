#include "cdc/lidar/scan_context.hpp"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <cmath>
#include <random>

namespace cdc::lidar {
namespace {

// A synthetic place: walls, boxes and poles around the sensor, sampled densely (seeded).
std::vector<Eigen::Vector3f> place(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<Eigen::Vector3f> pts;
  for (int obj = 0; obj < 25; ++obj) {
    const float r = 5 + 60 * u(rng), az = 6.2831853f * u(rng), h = 1 + 15 * u(rng), w = 0.5f + 4 * u(rng);
    for (int k = 0; k < 300; ++k) {
      const float a = az + (u(rng) - 0.5f) * w / r;
      pts.emplace_back(r * std::cos(a), r * std::sin(a), -2.0f + h * u(rng));
    }
  }
  for (int k = 0; k < 3000; ++k) {  // ground
    const float r = 3 + 70 * u(rng), a = 6.2831853f * u(rng);
    pts.emplace_back(r * std::cos(a), r * std::sin(a), -2.0f);
  }
  return pts;
}

std::vector<Eigen::Vector3f> rotated(const std::vector<Eigen::Vector3f>& pts, float yaw) {
  const Eigen::Matrix3f R = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  std::vector<Eigen::Vector3f> out;
  for (const auto& p : pts) out.push_back(R * p);
  return out;
}

TEST(ScanContext, ColumnShiftRecoversAKnownYawWithinOneSector) {
  const ScanContextParams p;
  const auto pts = place(1);
  const ScanContext ref = make_scan_context(pts, p);
  const double sector = 2 * M_PI / p.sectors;
  for (double yaw : {0.0, 0.3, 1.0, -2.0, 3.0}) {
    const ScanContext q = make_scan_context(rotated(pts, static_cast<float>(yaw)), p);
    const ScanContextMatch m = compare(q, ref);
    double err = std::remainder(m.yaw_rad - yaw, 2 * M_PI);
    EXPECT_LE(std::abs(err), sector + 1e-9) << "yaw " << yaw;
    EXPECT_LT(m.distance, 0.15) << "yaw " << yaw;
  }
  // A rotation by whole sectors is a pure column shift: the ring key is unchanged and the shift exact.
  const int k = 7;
  const ScanContext q = make_scan_context(rotated(pts, static_cast<float>(k * sector + 0.5 * sector)), p);
  const ScanContext q0 = make_scan_context(rotated(pts, static_cast<float>(0.5 * sector)), p);
  for (int r = 0; r < p.rings; ++r) {
    EXPECT_NEAR(q.ring_key[static_cast<size_t>(r)], q0.ring_key[static_cast<size_t>(r)], 1e-4) << "ring " << r;
  }
  const ScanContextMatch m = compare(q, q0);
  EXPECT_EQ(m.shift, p.sectors - k);
  EXPECT_NEAR(m.distance, 0.0, 1e-6);
  EXPECT_GT(compare(make_scan_context(place(2), p), ref).distance, 0.3);  // another place
}

TEST(ScanContext, RingKeyRetrievalFindsARotatedCopy) {
  const ScanContextParams p;
  ScanContextDatabase db(p.rings);
  for (uint32_t s = 0; s < 200; ++s) {
    db.add(make_scan_context(place(100 + s), p));
  }
  for (uint32_t s : {100u, 150u, 299u}) {
    const ScanContext q = make_scan_context(rotated(place(s), 1.234f), p);
    const auto c = db.query(q, 10, [](size_t) { return true; });
    ASSERT_FALSE(c.empty());
    EXPECT_EQ(c.front().id, s - 100) << "place " << s;
    // Excluding the right answer (e.g. recent keyframes of the same robot) leaves only poor matches.
    const auto x = db.query(q, 10, [&](size_t id) { return id != s - 100; });
    ASSERT_FALSE(x.empty());
    EXPECT_GT(x.front().match.distance, c.front().match.distance + 0.1);
  }
}

TEST(ScanContext, QuantisedDescriptorFitsTheWireBudgetAndMatchesAlike) {
  const ScanContextParams p;
  const auto pts = place(7);
  const ScanContext a = make_scan_context(pts, p);
  const ScanContext b = make_scan_context(rotated(pts, 0.7f), p);
  const QuantizedScanContext qa = quantize(a);
  EXPECT_LE(qa.bytes(), 1500u);
  const ScanContext back = dequantize(qa);
  for (size_t i = 0; i < a.cells.size(); ++i) {
    // The root rounded to the nearest step, except that an occupied cell never rounds down to empty.
    EXPECT_EQ(back.cells[i] > 0, a.cells[i] > 0) << "cell " << i;
    const float root = std::sqrt(a.cells[i]);
    EXPECT_NEAR(std::sqrt(back.cells[i]), root, a.cells[i] > 0 && root < qa.scale ? qa.scale : qa.scale / 2 + 1e-6);
  }
  // The ring key is recomputed from the dequantised cells: each ring's mean height, near the original's.
  ASSERT_EQ(back.ring_key.size(), a.ring_key.size());
  for (int r = 0; r < back.rings; ++r) {
    double mean = 0;
    for (int s = 0; s < back.sectors; ++s) mean += back.at(r, s);
    mean /= back.sectors;
    EXPECT_NEAR(back.ring_key[static_cast<size_t>(r)], mean, 1e-5) << "ring " << r;
    EXPECT_NEAR(back.ring_key[static_cast<size_t>(r)], a.ring_key[static_cast<size_t>(r)],
                0.02 * a.ring_key[static_cast<size_t>(r)] + 0.01)
        << "ring " << r;
  }
  const ScanContextMatch m = compare(b, a), mq = compare(b, back);
  EXPECT_EQ(m.shift, mq.shift);
  EXPECT_NEAR(m.distance, mq.distance, 0.01);
}

TEST(ScanContext, AViewFromBesideMatchesThePlaceSeenALaneAsideAndTurned) {
  // The place seen from 3.5 m to the left of its sensor, turned by pi (the opposite lane, driving
  // the other way): far from the original's descriptor, and matched by the original's view from there.
  const std::vector<Eigen::Vector3f> here = place(11);
  std::vector<Eigen::Vector3f> aside;
  for (const auto& p : here) aside.push_back(p - Eigen::Vector3f(0, 3.5f, 0));
  aside = rotated(aside, 3.1415927f);
  const ScanContextParams sp;
  const ScanContext other_lane = make_scan_context(aside, sp);
  const ScanContextMatch plain = compare(other_lane, make_scan_context(here, sp));
  const ScanContextMatch view = compare(other_lane, make_scan_context(here, sp, Eigen::Vector3f(0, 3.5f, 0)));
  EXPECT_GT(plain.distance, 0.3);
  EXPECT_LT(view.distance, 0.05);
  EXPECT_NEAR(std::abs(view.yaw_rad), M_PI, 2 * M_PI / sp.sectors);
  // The view from the sensor's own place is the plain descriptor.
  EXPECT_EQ(make_scan_context(here, sp, Eigen::Vector3f::Zero()).cells, make_scan_context(here, sp).cells);
}

}  // namespace
}  // namespace cdc::lidar
