#include "cdc/dds/compact.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace cdc::dds::compact {
namespace {

using ::testing::HasSubstr;

TEST(Compact, BytesRoundTripLosslessly) {
  std::mt19937 rng(7);
  std::vector<uint8_t> raw(1200);
  for (auto& b : raw) b = rng() % 3 == 0 ? 0 : static_cast<uint8_t>(rng() % 256);
  const std::vector<uint8_t> packed = deflate_bytes(raw.data(), raw.size());
  std::vector<uint8_t> back;
  EXPECT_EQ(inflate_bytes(packed.data(), packed.size(), raw.size(), back), "");
  EXPECT_EQ(back, raw);
}

TEST(Compact, BrokenPackedBytesAreNamed) {
  const std::vector<uint8_t> raw(100, 9);
  std::vector<uint8_t> packed = deflate_bytes(raw.data(), raw.size());
  std::vector<uint8_t> back;
  EXPECT_THAT(inflate_bytes(packed.data(), 0, 100, back), HasSubstr("empty"));
  EXPECT_THAT(inflate_bytes(packed.data(), packed.size() - 3, 100, back), HasSubstr("truncated packed data"));
  EXPECT_THAT(inflate_bytes(packed.data(), packed.size(), 101, back), HasSubstr("unpacks to 100 bytes, 101 expected"));
  EXPECT_THAT(inflate_bytes(packed.data(), packed.size(), 99, back), HasSubstr("more than the 99 bytes"));
  packed.push_back(0);
  EXPECT_THAT(inflate_bytes(packed.data(), packed.size(), 100, back), HasSubstr("1 bytes after the end"));
  const std::vector<uint8_t> garbage(50, 0xab);
  EXPECT_THAT(inflate_bytes(garbage.data(), garbage.size(), 100, back), HasSubstr("corrupt packed data"));
}

TEST(Compact, PointsComeBackWithinHalfAStepAndPackSmall) {
  // A keyframe-like cloud: 6,000 points within 80 m.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-80.0f, 80.0f), h(-2.0f, 10.0f);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 6000; ++i) pts.emplace_back(u(rng), u(rng), h(rng));
  for (const float res : {0.01f, 0.02f}) {
    const PackedCloud pc = pack_points(pts, res);
    EXPECT_EQ(pc.count, 6000u);
    EXPECT_EQ(pc.dropped, 0u);
    EXPECT_LT(pc.bytes.size(), 6000u * 6u) << "no smaller than raw int16 points";
    std::vector<Eigen::Vector3f> back;
    ASSERT_EQ(unpack_points(pc.bytes.data(), pc.bytes.size(), pc.count, res, back), "");
    ASSERT_EQ(back.size(), pts.size());
    // Order is not kept: match every original to its nearest decoded point through sorting both.
    auto key = [res](const Eigen::Vector3f& p) {
      return std::array<long, 3>{std::lround(p.x() / res), std::lround(p.y() / res), std::lround(p.z() / res)};
    };
    std::vector<std::pair<std::array<long, 3>, Eigen::Vector3f>> a, b;
    for (const auto& p : pts) a.emplace_back(key(p), p);
    for (const auto& p : back) b.emplace_back(key(p), p);
    auto less = [](const auto& x, const auto& y) { return x.first < y.first; };
    std::sort(a.begin(), a.end(), less);
    std::sort(b.begin(), b.end(), less);
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_LE((a[i].second - b[i].second).cwiseAbs().maxCoeff(), res / 2 + 1e-4f) << "point " << i;
    }
  }
}

TEST(Compact, SurfacesPackInUnderThreeBytesPerPointAtOneCentimetre) {
  // What verification clouds look like: one centroid per 0.4 m voxel of a street (ground out to
  // 40 m, two facades, a few poles), each anywhere inside its voxel. Coding the points in Morton
  // order keeps neighbours' deltas small; per-axis deltas of points sorted by x took ~3.3 B each.
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> in_voxel(0.0f, 0.4f);
  std::vector<Eigen::Vector3f> pts;
  auto centroid = [&](float x, float y, float z) {
    pts.emplace_back(x + in_voxel(rng), y + in_voxel(rng), z + in_voxel(rng));
  };
  for (float x = -40.0f; x < 40.0f; x += 0.4f) {
    for (float y = -8.0f; y < 8.0f; y += 0.4f) centroid(x, y, -1.8f);  // the road
    for (float z = -1.8f; z < 8.0f; z += 0.4f) {
      centroid(x, -8.4f, z);  // the facades
      centroid(x, 8.0f, z);
    }
  }
  for (float x = -36.0f; x < 40.0f; x += 12.0f) {
    for (float z = -1.4f; z < 5.0f; z += 0.4f) centroid(x, 6.0f, z);  // poles
  }
  const PackedCloud pc = pack_points(pts, 0.01f);
  ASSERT_EQ(pc.count, pts.size());
  const double per_point = static_cast<double>(pc.bytes.size()) / static_cast<double>(pts.size());
  EXPECT_LT(per_point, 3.0) << pts.size() << " points in " << pc.bytes.size() << " bytes";
  std::vector<Eigen::Vector3f> back;
  ASSERT_EQ(unpack_points(pc.bytes.data(), pc.bytes.size(), pc.count, pc.resolution_m, back), "");
  EXPECT_EQ(back.size(), pts.size());
}

TEST(Compact, PointsOutsideTheInt16RangeAreDroppedAndCounted) {
  const std::vector<Eigen::Vector3f> pts = {{1, 1, 1}, {400, 0, 0}, {0, -330, 0}, {-327, 327, 0}};
  const PackedCloud pc = pack_points(pts, 0.01f);
  EXPECT_EQ(pc.count, 2u);
  EXPECT_EQ(pc.dropped, 2u);
  std::vector<Eigen::Vector3f> back;
  ASSERT_EQ(unpack_points(pc.bytes.data(), pc.bytes.size(), pc.count, pc.resolution_m, back), "");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_NEAR(back[0].x(), -327.0f, 0.006f);
  EXPECT_NEAR(back[1].z(), 1.0f, 0.006f);
}

// The grid's whole int16 range packs, its lowest step (-32768) included, so that every cloud
// unpack_points returns packs again unchanged.
TEST(Compact, BothEndsOfTheInt16RangePack) {
  const float res = 0.064f;
  const std::vector<Eigen::Vector3f> pts = {{-32768 * res, -32768 * res, -32768 * res},
                                            {32767 * res, 32767 * res, 32767 * res}};
  const PackedCloud pc = pack_points(pts, res);
  EXPECT_EQ(pc.dropped, 0u);
  ASSERT_EQ(pc.count, 2u);
  std::vector<Eigen::Vector3f> back;
  ASSERT_EQ(unpack_points(pc.bytes.data(), pc.bytes.size(), pc.count, res, back), "");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_FLOAT_EQ(back[0].x(), -32768 * res);
  EXPECT_FLOAT_EQ(back[1].z(), 32767 * res);
}

TEST(Compact, RandomAndMutatedInputNeverCrashes) {
  // Network input: random bytes, and valid packed data with bytes flipped, truncated or extended,
  // must come back as a reason or as exactly the size asked for (run under the asan preset too).
  std::mt19937 rng(99);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 500; ++i)
    pts.emplace_back(0.1f * static_cast<float>(i % 37), 0.2f * static_cast<float>(i % 11), 1.0f);
  const PackedCloud good = pack_points(pts, 0.01f);
  std::vector<Eigen::Vector3f> out;
  std::vector<uint8_t> bytes;
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<uint8_t> data = good.bytes;
    switch (trial % 4) {
      case 0:
        data.resize(rng() % 200);
        for (auto& b : data) b = static_cast<uint8_t>(rng());
        break;
      case 1:
        data[rng() % data.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
        break;
      case 2:
        data.resize(rng() % data.size());
        break;
      default:
        data.push_back(static_cast<uint8_t>(rng()));
        break;
    }
    const uint32_t count = trial % 5 == 0 ? static_cast<uint32_t>(rng() % 1000) : good.count;
    const std::string err = unpack_points(data.data(), data.size(), count, 0.01f, out);
    if (err.empty()) {
      EXPECT_EQ(out.size(), count);
    }
    const std::string err2 = inflate_bytes(data.data(), data.size(), 6 * size_t{count}, bytes);
    if (err2.empty()) {
      EXPECT_EQ(bytes.size(), 6 * size_t{count});
    }
  }
}

TEST(Compact, EmptyCloudAndBadArguments) {
  const PackedCloud empty = pack_points({}, 0.01f);
  std::vector<Eigen::Vector3f> back{{1, 2, 3}};
  EXPECT_EQ(unpack_points(nullptr, 0, 0, 0.01f, back), "");
  EXPECT_TRUE(back.empty());
  EXPECT_EQ(empty.count, 0u);
  const std::vector<uint8_t> stray = deflate_bytes(nullptr, 0);
  EXPECT_THAT(unpack_points(stray.data(), stray.size(), 0, 0.01f, back), HasSubstr("for 0 points"));
  EXPECT_THAT(unpack_points(empty.bytes.data(), empty.bytes.size(), 4, -1.0f, back), HasSubstr("resolution_m"));
}

// Found by the compact fuzz harness: a cloud with no points in range (a reply for an empty keyframe) must
// pack to what its receiver accepts, not to a zlib stream that unpack_points refuses for 0 points.
TEST(Compact, CloudWithNoPointsInRangeRoundTrips) {
  for (const std::vector<Eigen::Vector3f>& pts : {std::vector<Eigen::Vector3f>{}, {{1000, 0, 0}, {0, 0, -400}}}) {
    const PackedCloud pc = pack_points(pts, 0.01f);
    EXPECT_EQ(pc.count, 0u);
    EXPECT_EQ(pc.dropped, pts.size());
    EXPECT_TRUE(pc.bytes.empty());
    std::vector<Eigen::Vector3f> back{{1, 2, 3}};
    EXPECT_EQ(unpack_points(pc.bytes.data(), pc.bytes.size(), pc.count, pc.resolution_m, back), "");
    EXPECT_TRUE(back.empty());
  }
}

}  // namespace
}  // namespace cdc::dds::compact
