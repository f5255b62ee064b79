#include "cdc/dds_lidar/descriptor_convert.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <vector>

namespace cdc::dds_lidar {
namespace {

// A seeded cloud of points scattered within 40 m around the sensor.
lidar::QuantizedScanContext some_descriptor() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> xy(-40.0f, 40.0f), z(-1.5f, 6.0f);
  std::vector<Eigen::Vector3f> points(4000);
  for (auto& p : points) p = Eigen::Vector3f(xy(rng), xy(rng), z(rng));
  return lidar::quantize(lidar::make_scan_context(points, lidar::ScanContextParams{}));
}

TEST(DescriptorConvert, RoundTripGivesTheDequantisedDescriptor) {
  const lidar::QuantizedScanContext q = some_descriptor();
  cdc_msg_Descriptor m{};
  std::vector<uint8_t> cells;
  descriptor_to_msg(q, 80.0f, m, cells);
  EXPECT_EQ(m.rings, q.rings);
  EXPECT_EQ(m.sectors, q.sectors);
  EXPECT_EQ(m.max_range, 80.0f);
  EXPECT_EQ(m.quant_scale, q.scale);
  EXPECT_EQ(m.packed_cells._buffer, cells.data());
  EXPECT_EQ(m.packed_cells._length, cells.size());
  EXPECT_LT(cells.size(), q.cells.size());  // packed

  const lidar::ScanContext back = descriptor_from_msg(m);
  const lidar::ScanContext expected = lidar::dequantize(q);
  EXPECT_EQ(back.rings, expected.rings);
  EXPECT_EQ(back.sectors, expected.sectors);
  EXPECT_EQ(back.cells, expected.cells);
  EXPECT_EQ(back.ring_key, expected.ring_key);
}

TEST(DescriptorConvert, CellsThatDoNotUnpackAreNamed) {
  const lidar::QuantizedScanContext q = some_descriptor();
  cdc_msg_Descriptor m{};
  std::vector<uint8_t> cells;
  descriptor_to_msg(q, 80.0f, m, cells);
  m.sectors = static_cast<uint16_t>(m.sectors - 1);  // the cells no longer fill rings x sectors
  EXPECT_THAT([&] { descriptor_from_msg(m); },
              ::testing::ThrowsMessage<std::invalid_argument>(::testing::HasSubstr("descriptor packed_cells")));
  m.sectors = static_cast<uint16_t>(q.sectors);
  m.packed_cells._length = 3;  // truncated
  EXPECT_THROW(descriptor_from_msg(m), std::invalid_argument);
}

}  // namespace
}  // namespace cdc::dds_lidar
