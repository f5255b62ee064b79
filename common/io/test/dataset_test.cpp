#include "cdc/io/dataset.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/error.hpp"
#include "cdc/io/kitti.hpp"
#include "temp_dir.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

namespace cdc::io {
namespace {
namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) { return test::fresh_temp_dir("io_" + name); }

Sweep make_sweep(int n, float base, bool times) {
  Sweep s;
  for (int i = 0; i < n; ++i) {
    CloudPoint p;
    p.x = base + static_cast<float>(i);
    p.y = -base;
    p.z = 0.5f * static_cast<float>(i);
    p.intensity = 0.25f;
    if (times) {
      p.time_offset = 0.001f * static_cast<float>(i);
      p.ring = static_cast<uint16_t>(i % 16);
    }
    s.points.push_back(p);
  }
  s.has_time = s.has_ring = times;
  s.has_intensity = true;
  return s;
}

TEST(Dataset, WriterAndReaderRoundTripSweepsTimesPosesImuAndInfo) {
  const fs::path root = temp_dir("roundtrip");
  const fs::path dir = root / "ds";
  {
    DatasetWriter w(dir);
    w.add_sweep(0, 1'000'000'000, make_sweep(5, 1, true));
    w.add_sweep(0, 1'100'000'001, make_sweep(7, 2, true));
    w.add_sweep(1, 1'050'000'000, make_sweep(3, 3, false));
    geometry::Trajectory gt{{1'000'000'000, Eigen::Isometry3d::Identity()},
                            {1'100'000'001, Eigen::Isometry3d::Identity()}};
    gt[1].pose.translation() = Eigen::Vector3d(1, 2, 3);
    w.set_groundtruth(0, gt);
    w.set_imu(0, {{1'000'000'000, Eigen::Vector3d(0, 0, 9.81), Eigen::Vector3d(0.1, 0, 0)},
                  {1'005'000'000, Eigen::Vector3d(0, 0.5, 9.81), Eigen::Vector3d(0, 0.2, 0)}});
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(-0.1, 0, -0.05);
    w.set_calib(0, T, "test", 200);
    w.set_radio("t,a,b,in_range,distance,loss\n", "a,b,start,end\n");
    DatasetInfo info;
    info.source = "test";
    info.point_times = PointTimes::kSensor;
    info.sweep_period_s = 0.1;
    const DatasetInfo out = w.commit(info);
    EXPECT_EQ(out.robots, 2u);
    EXPECT_EQ(out.scans, 3u);
    EXPECT_EQ(out.points, 15u);
  }
  EXPECT_FALSE(fs::exists(root / "ds.partial"));
  const DatasetInfo info = read_dataset_info(dir);
  EXPECT_EQ(info.source, "test");
  EXPECT_EQ(info.scans, 3u);
  std::map<uint32_t, geometry::Trajectory> gt;
  const std::vector<DatasetScan> scans = list_dataset_scans(dir.string(), 0, &gt);
  ASSERT_EQ(scans.size(), 3u);
  EXPECT_EQ(scans[0].stamp_ns, 1'000'000'000);
  EXPECT_EQ(scans[1].robot, 1u);
  EXPECT_EQ(scans[2].stamp_ns, 1'100'000'001);  // exact nanoseconds through times.txt
  ASSERT_TRUE(scans[2].truth.has_value());
  EXPECT_NEAR(scans[2].truth->translation().z(), 3.0, 1e-9);
  EXPECT_TRUE(gt[1].empty());
  const Sweep a = read_dataset_scan(scans[2]);
  EXPECT_TRUE(a.has_time);
  ASSERT_EQ(a.points.size(), 7u);
  EXPECT_FLOAT_EQ(a.points[6].x, 8.0f);
  EXPECT_FLOAT_EQ(a.points[6].time_offset, 0.006f);
  EXPECT_EQ(a.points[6].ring, 6);
  const Sweep b = read_dataset_scan(scans[1]);
  EXPECT_FALSE(b.has_time) << "robot 1's sweeps have no per-point times and none may be invented";
  EXPECT_FALSE(b.has_ring);
  EXPECT_FLOAT_EQ(b.points[0].time_offset, 0.0f);
  const auto imu = read_dataset_imu(dir / "robot_0" / "imu.csv");
  ASSERT_EQ(imu.size(), 2u);
  EXPECT_EQ(imu[1].stamp_ns, 1'005'000'000);
  EXPECT_NEAR(imu[1].accel.y(), 0.5, 1e-9);
  EXPECT_TRUE(read_dataset_imu(dir / "robot_1" / "imu.csv").empty());
  EXPECT_NEAR(read_dataset_calib(dir / "robot_0" / "calib.yaml").translation().x(), -0.1, 1e-9);
  fs::remove_all(root);
}

TEST(Dataset, AWriterThatIsNotCommittedLeavesNothingBehind) {
  const fs::path root = temp_dir("abandon");
  {
    DatasetWriter w(root / "ds");
    w.add_sweep(0, 0, make_sweep(2, 0, false));
    EXPECT_TRUE(fs::exists(root / "ds.partial"));
  }
  EXPECT_FALSE(fs::exists(root / "ds"));
  EXPECT_FALSE(fs::exists(root / "ds.partial"));
  fs::remove_all(root);
}

TEST(Dataset, WriterRefusesSweepsOutOfOrderMixedTimesAnExistingFolderAndAGapInRobots) {
  const fs::path root = temp_dir("refuse");
  DatasetWriter w(root / "ds");
  w.add_sweep(0, 100, make_sweep(2, 0, true));
  EXPECT_THROW(w.add_sweep(0, 100, make_sweep(2, 0, true)), std::runtime_error);
  EXPECT_THROW(w.add_sweep(0, 200, make_sweep(2, 0, false)), std::runtime_error);
  w.add_sweep(2, 100, make_sweep(2, 0, false));
  EXPECT_THROW(w.commit({}), std::runtime_error);  // robot 1 has no sweeps
  fs::create_directories(root / "exists");
  EXPECT_THROW(DatasetWriter(root / "exists"), std::runtime_error);
  fs::remove_all(root);
}

TEST(Dataset, ReaderNamesWhatIsWrong) {
  const fs::path root = temp_dir("bad");
  std::ofstream(root / "odd.bin") << "0123456789";  // 10 bytes
  try {
    read_kitti_bin(root / "odd.bin");
    FAIL() << "a 10-byte sweep was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("odd.bin"), std::string::npos) << e.what();
  }
  std::ofstream(root / "dataset.json") << "{\"point_times\": \"sometimes\"}";
  EXPECT_THROW(read_dataset_info(root), FormatError);
  // Counts and ids are integers in their type's range: a float, a negative number or one too large
  // is refused with the field's name, never cast.
  for (const char* bad : {"{\"central_id\": 5.5e32}", "{\"central_id\": 4294967296}", "{\"robots\": -3}",
                          "{\"scans\": 2.5}", "{\"points\": \"many\"}"}) {
    std::ofstream(root / "dataset.json", std::ios::trunc) << bad;
    try {
      read_dataset_info(root);
      FAIL() << bad << " was accepted";
    } catch (const FormatError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("must be an integer"), std::string::npos) << what;
    }
  }
  std::ofstream(root / "dataset.json", std::ios::trunc) << "{\"central_id\": 4294967295, \"robots\": 3}";
  EXPECT_EQ(read_dataset_info(root).central_id, 4294967295u);
  EXPECT_EQ(read_dataset_info(root).robots, 3u);
  fs::create_directories(root / "robot_0");
  std::ofstream(root / "robot_0" / "times.txt") << "0.0\n0.1\n";
  fs::create_directories(root / "robot_0" / "velodyne");
  write_kitti_bin(root / "robot_0" / "velodyne" / "000000.bin", make_sweep(2, 0, false).points);
  try {
    list_dataset_scans(root.string());
    FAIL() << "a missing sweep was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("000001.bin"), std::string::npos) << e.what();
  }
  std::ofstream(root / "robot_0" / "imu.csv") << "t,ax,ay,az,gx,gy,gz\n0.0,1,2,3,4,5,6\n0.1,1,2,3\n";
  try {
    read_dataset_imu(root / "robot_0" / "imu.csv");
    FAIL() << "a short IMU line was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("imu.csv:3"), std::string::npos) << e.what();
  }
  fs::remove_all(root);
}

// times.txt and velodyne/ must agree: a reader never takes part of a robot's sweeps without a word. And no IMU or
// calibration value may be NaN or infinite.
TEST(Dataset, TimesThatDisagreeWithTheSweepsAndValuesThatAreNotFiniteAreRefused) {
  const fs::path root = temp_dir("count");
  fs::create_directories(root / "robot_0" / "velodyne");
  for (const char* n : {"000000.bin", "000001.bin", "000002.bin"}) {
    write_kitti_bin(root / "robot_0" / "velodyne" / n, make_sweep(2, 0, false).points);
  }
  std::ofstream(root / "robot_0" / "times.txt") << "0.0\n0.1\n";
  try {
    list_dataset_scans(root.string());
    FAIL() << "two times for three sweeps were accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("times.txt: lists 2 sweeps but"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("velodyne holds 3"), std::string::npos) << e.what();
  }
  std::ofstream(root / "robot_0" / "times.txt") << "0.0\n0.1\n0.2\n";
  EXPECT_EQ(list_dataset_scans(root.string()).size(), 3u);
  std::ofstream(root / "robot_0" / "imu.csv") << "t,ax,ay,az,gx,gy,gz\n0.0,1,2,3,4,5,6\n0.1,1,nan,3,4,5,6\n";
  EXPECT_THAT([&] { read_dataset_imu(root / "robot_0" / "imu.csv"); },
              ::testing::ThrowsMessage<FormatError>(::testing::HasSubstr("imu.csv:3: a value is not a finite number")));
  std::ofstream(root / "robot_0" / "calib.yaml") << "T_lidar_imu: {position: [0, inf, 0], orientation: [0, 0, 0, 1]}\n";
  EXPECT_THAT([&] { read_dataset_calib(root / "robot_0" / "calib.yaml"); },
              ::testing::ThrowsMessage<FormatError>(::testing::HasSubstr("calib.yaml:1: T_lidar_imu holds a value")));
  fs::remove_all(root);
}

// Found by the cloud fuzz harness: PCL's PCD reader trusts the header (a repeated WIDTH line before
// FIELDS crashed it); read_cloud_file checks the header first and names what is wrong.
TEST(CloudFiles, PcdHeadersOutOfOrderAreRefusedBeforePcl) {
  const fs::path root = temp_dir("pcd");
  const std::string fields = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
  const std::string size = "WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\n";
  const std::string data = "DATA ascii\n1 2 3\n4 5 6\n";
  std::ofstream(root / "good.pcd") << "# .PCD v0.7\nVERSION 0.7\n" << fields << size << data;
  EXPECT_EQ(read_cloud_file(root / "good.pcd").points.size(), 2u);
  auto refused = [&](const std::string& text, const std::string& reason) {
    std::ofstream(root / "bad.pcd") << text;
    try {
      read_cloud_file(root / "bad.pcd");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.pcd:"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
  };
  refused("VERSION 0.7\nWIDTH 4\nHEIGHT 1\n" + fields + size + data, "FIELDS missing before WIDTH");
  refused(fields + "WIDTH 2\n" + size + data, "WIDTH repeated or out of the PCD header's order");
  refused("FIELDS x y z\nSIZE 4 4\n", "SIZE has 2 values for 3 fields");
  refused(fields + size + "DATA compressed\n", "DATA must be ascii");
  refused(fields + "VIEWPO.7\n" + size + data, "'VIEWPO.7' is not a PCD header entry");
  refused(fields + size + "DATA binary\n" + std::string(20, '\0'), "binary data of 20 bytes, the header announces 24");
  refused(fields + size + "DATA binary_compressed\n\x40\0\0\0", "compressed data does not match");
  fs::remove_all(root);
}

// Found by the cloud fuzz harness: a binary PCD whose data starts with a "COLUMNS" line made PCL's
// reader throw std::length_error inside a noexcept function (std::terminate). The io library's own
// reader takes the bytes after DATA binary as data: four points of six fields, trailing bytes ignored.
TEST(CloudFiles, BinaryPcdDataThatLooksLikeAHeaderLineIsData) {
  const fs::path root = temp_dir("pcd_columns");
  const std::string header =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity ring time\nSIZE 4 4 4 4 2 4\nTYPE F F F F U F\n"
      "COUNT 1 1 1 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA binary\n";
  const unsigned char data[] = {'C',  'O',  'L',  'U',  'M',  'N',  'S',  0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00,
                                0x80, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
                                0x00, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x00, 0xbf, 0x00, 0x00, 0x80, 0x3e, 0xcd,
                                0xcc, 0xcc, 0x3d, 0x01, 0x00, 0x6f, 0x12, 0x83, 0x3a, 0x00, 0x00, 0x40, 0x40, 0x00,
                                0x00, 0x80, 0xbf, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x3f, 0xcd, 0xcc, 0x4c, 0x3e,
                                0x02, 0x00, 0x6f, 0x12, 0x03, 0x3b, 0x00, 0x00, 0x80, 0x40, 0x00, 0x00, 0xc0, 0xbf,
                                0x00, 0x00, 0x40, 0x3f, 0x9a, 0x99, 0x99, 0x3e, 0x03, 0x00, 0xa6, 0x9b, 0x44, 0x3b};
  std::ofstream(root / "columns.pcd", std::ios::binary)
      << header << std::string(reinterpret_cast<const char*>(data), sizeof data);
  const Sweep s = read_cloud_file(root / "columns.pcd");
  ASSERT_EQ(s.points.size(), 4u);
  EXPECT_TRUE(s.has_intensity && s.has_ring && s.has_time);
  float x0 = 0;
  std::memcpy(&x0, "COLU", 4);
  EXPECT_EQ(s.points[0].x, x0);
  EXPECT_EQ(s.points[3].x, 0.2f);
  EXPECT_EQ(s.points[3].ring, 49088);
  EXPECT_EQ(s.points[3].time_offset, 0.75f);
  fs::remove_all(root);
}

// The PCD reader's data kinds: ascii with multi-valued and 8-byte fields skipped, binary_compressed
// (LZF literal runs and a back-reference, columns per field), and its errors naming line or byte.
TEST(CloudFiles, PcdAsciiAndCompressedDataAreDecodedAndErrorsArePlaced) {
  const fs::path root = temp_dir("pcd_kinds");
  std::ofstream(root / "ascii.pcd") << "VERSION .7\nFIELDS x y z rgb normal id\nSIZE 4 4 8 4 4 8\n"
                                       "TYPE F F F U F U\nCOUNT 1 1 1 1 3 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n"
                                       "DATA ascii\n1 2 3 255 0 0 1 9\n\n-4.5 5e1 nan 0 1 1 1 18446744073709551615\n";
  const Sweep a = read_cloud_file(root / "ascii.pcd");
  ASSERT_EQ(a.points.size(), 1u);  // the second point's z is not finite
  EXPECT_EQ(a.points[0].x, 1.0f);
  EXPECT_EQ(a.points[0].z, 3.0f);
  EXPECT_FALSE(a.has_intensity);

  // x0 = x1 = 1.5, y = 2, 3, z = 4, 5: columns x0 x1 y0 y1 z0 z1, x1 as a back-reference to x0.
  auto f32 = [](float v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  const std::string lzf = std::string(1, '\x03') + f32(1.5f) + std::string("\x40\x03", 2) + std::string(1, '\x0f') +
                          f32(2) + f32(3) + f32(4) + f32(5);
  const uint32_t sizes[2] = {static_cast<uint32_t>(lzf.size()), 24};
  const std::string head = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n";
  std::ofstream(root / "lzf.pcd", std::ios::binary) << head << "DATA binary_compressed\n"
                                                    << std::string(reinterpret_cast<const char*>(sizes), 8) << lzf;
  const Sweep c = read_cloud_file(root / "lzf.pcd");
  ASSERT_EQ(c.points.size(), 2u);
  EXPECT_EQ(c.points[1].x, 1.5f);
  EXPECT_EQ(c.points[1].y, 3.0f);
  EXPECT_EQ(c.points[1].z, 5.0f);

  auto refused = [&](const std::string& text, const std::string& reason) {
    std::ofstream(root / "bad.pcd", std::ios::binary) << text;
    try {
      read_cloud_file(root / "bad.pcd");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
  };
  refused(head + "DATA ascii\n1 2 3\n4 5\n", "bad.pcd:9: 2 values, the fields need 3");
  refused(head + "DATA ascii\n1 2 3\n4 five 6\n", "bad.pcd:9: 'five' is not a value of field 'y'");
  refused(head + "DATA ascii\n1 2 3\n", "ascii data holds 1 points, POINTS is 2");
  refused(head + "DATA ascii\n1 2 3\n4 5 6\n7 8 9\n", "bad.pcd:10: more points than POINTS 2");
  refused("FIELDS x\nSIZE 2\nTYPE F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n\0\0", "a float of 2 bytes");
  const uint32_t far[2] = {3, 24};
  refused(head + "DATA binary_compressed\n" + std::string(reinterpret_cast<const char*>(far), 8) +
              std::string("\x20\x05\x00", 3),
          "bad.pcd: LZF data at byte 92: refers to 6 bytes back, before the start");
  fs::remove_all(root);
}

TEST(KittiSequence, AMissingSweepATooShortTimesFileAndPosesAreNamed) {
  const fs::path root = temp_dir("kitti");
  fs::create_directories(root / "velodyne");
  for (const char* n : {"000000.bin", "000001.bin", "000003.bin"})
    write_kitti_bin(root / "velodyne" / n, make_sweep(3, 0, false).points);
  try {
    read_kitti_sequence(root);
    FAIL() << "a missing sweep was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("000002.bin"), std::string::npos) << e.what();
  }
  KittiSequenceOptions o;
  o.allow_gaps = true;
  EXPECT_EQ(read_kitti_sequence(root, o).frames, (std::vector<size_t>{0, 1, 3}));
  write_kitti_bin(root / "velodyne" / "000002.bin", make_sweep(3, 0, false).points);
  std::ofstream(root / "times.txt") << "0.0\n0.1\n0.2\n";
  try {
    read_kitti_sequence(root);
    FAIL() << "a times file too short was accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("times.txt"), std::string::npos) << e.what();
  }
  std::ofstream(root / "times.txt") << "0.0\n0.1\n0.2\n0.3\n";
  std::ofstream(root / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n";
  o = {};
  o.poses = root / "poses.txt";
  o.poses_frame = KittiPosesFrame::kLidar;
  EXPECT_THROW(read_kitti_sequence(root, o), FormatError);
  const KittiSequence seq = read_kitti_sequence(root);
  EXPECT_EQ(seq.stamps_ns[3], 300'000'000);
  EXPECT_TRUE(seq.times_from_file);
  fs::remove_all(root);
}

TEST(KittiSequence, RealSweepsOfSequence00TakeTheirGroundTruthInTheLidarFrame) {
  const char* env = std::getenv("CDC_DATA_DIR");
  const fs::path data = env != nullptr ? env : "../shared/data";
  if (!fs::exists(data / "kitti/scans/seq00"))
    GTEST_SKIP() << "reference data not found at " << data << " (set CDC_DATA_DIR)";
  KittiSequenceOptions o;
  o.allow_gaps = true;
  o.poses = data / "kitti/poses/00.txt";
  o.calib = data / "kitti/calib_Tr.txt";
  o.calib_key = "Tr_00_02";
  const KittiSequence seq = read_kitti_sequence(data / "kitti/scans/seq00", o);
  ASSERT_EQ(seq.frames, (std::vector<size_t>{94, 95, 198, 199}));
  EXPECT_EQ(seq.stamps_ns[2], 19'800'000'000);
  ASSERT_EQ(seq.poses.size(), 4u);
  // The car drives forward along the LiDAR's x axis: consecutive poses differ mostly in x.
  const Eigen::Vector3d d = (seq.poses[0].pose.inverse() * seq.poses[1].pose).translation();
  EXPECT_GT(std::abs(d.x()), 5 * std::abs(d.y()));
  EXPECT_GT(std::abs(d.x()), 5 * std::abs(d.z()));
  const std::vector<CloudPoint> pts = read_kitti_bin(seq.sweeps[0]);
  EXPECT_GT(pts.size(), 100'000u);
}

}  // namespace
}  // namespace cdc::io
