// cdc-import: real recordings into the dataset layout that cdc-sim play, cdc-launch, cdc-odometry,
// cdc-loops and cdc-experiment read (see cdc/io/dataset.hpp).
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/io/bag.hpp"
#include "import.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <iostream>

namespace fs = std::filesystem;
using namespace cdc;

namespace {

void add_common(CLI::App* c, sim::ImportOptions& o, std::vector<double>& central_position) {
  c->add_option("--out", o.out, "dataset folder to write (written as OUT.partial, renamed when complete)")->required();
  c->add_flag("--overwrite", o.overwrite, "replace an existing dataset folder");
  c->add_option("--name", o.name, "dataset name (default: the folder's name)");
  c->add_option("--robots", o.robots, "split into K robots driving at the same time (the paper's protocol)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  c->add_option("--overlap", o.overlap, "fraction of each robot's piece shared with the next")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.9));
  cdc::config::add_number_option(*c, "--time-shift", o.time_shift_s,
                                 "robot k starts k x this many seconds after robot 0", 0, 3600);
  cdc::config::add_number_option(*c, "--max-scans", o.max_scans, "at most this many sweeps per robot (0: all)", 0, 1e6);
  c->add_option("--central-range", o.radio.central_range_m,
                "the central's communication range CR_0 [m]: the radio follows the poses (required with poses and "
                "several robots)")
      ->check(cdc::config::cli_range(0.1, 1e6));
  c->add_option("--robot-range", o.radio.robot_range_m, "robot-to-robot range [m] (default: the central's)")
      ->check(cdc::config::cli_range(0.1, 1e6));
  cdc::config::add_number_option(*c, "--central-robot", o.radio.central_robot,
                                 "the central rides on this robot (-1: fixed, see --central-position)", -1, 63);
  c->add_option("--central-position", central_position, "fixed central position x y z [m] in the poses' world")
      ->expected(3)
      ->check(cdc::config::cli_range(-1e7, 1e7));
  cdc::config::add_number_option(*c, "--central-id", o.radio.central_id, "the central node's id in the radio", 0, 254);
  c->add_option("--radio-timeline", o.radio.timeline,
                "CSV a,b,start,end [s]: periods when nodes a and b are out of range")
      ->check(CLI::ExistingFile);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-import: turns a real recording into a cdc-slam dataset folder (robot_K/velodyne, times, poses, IMU, "
      "radio),\n"
      "optionally split into K overlapping robots driving at the same time.\n"
      "  cdc-import kitti SEQ_DIR --out DIR [--poses 00.txt --calib calib.txt] [--robots 3 --central-range 150]\n"
      "  cdc-import sweeps DIR --out DIR [--times times.txt] [--poses poses.txt] [--period 0.1]\n"
      "  cdc-import bag BAG --out DIR [--lidar-topic T] [--imu-topic T] [--calibration VLP16.yaml]"};
  app.require_subcommand(1);
  sim::ImportOptions o;
  std::vector<double> central_position;

  CLI::App* kitti = app.add_subcommand(
      "kitti", "a KITTI odometry sequence folder (velodyne/, times.txt, calib.txt) or a velodyne folder");
  std::string kitti_dir, poses_frame = "camera", point_times = "none";
  io::KittiSequenceOptions ko;
  double kitti_period = 0.1;
  kitti->add_option("sequence", kitti_dir, "sequence folder")->required()->check(CLI::ExistingDirectory);
  kitti->add_option("--poses", ko.poses, "poses, 3x4 row-major per frame (KITTI ground truth)")
      ->check(CLI::ExistingFile);
  kitti
      ->add_option("--poses-frame", poses_frame,
                   "camera: KITTI ground truth T_world_cam0 (needs the calibration); lidar: LiDAR poses")
      ->check(CLI::IsMember({"camera", "lidar"}))
      ->capture_default_str();
  kitti->add_option("--calib", ko.calib, "calibration holding Tr (default SEQ_DIR/calib.txt)")
      ->check(CLI::ExistingFile);
  kitti->add_option("--calib-key", ko.calib_key, "the calibration entry holding T_cam0_velo")->capture_default_str();
  kitti
      ->add_option("--times", ko.times,
                   "sweep times, seconds per line (default SEQ_DIR/times.txt, else frame x period)")
      ->check(CLI::ExistingFile);
  kitti->add_flag("--allow-gaps", ko.allow_gaps, "accept missing frame numbers (else a missing sweep is an error)");
  cdc::config::add_number_option(*kitti, "--period", kitti_period, "sweep period [s]", 0.001, 10);
  kitti
      ->add_option("--point-times", point_times,
                   "none: the sweeps are taken as motion-compensated; azimuth: per-point times from the azimuth (a raw "
                   "spinning sweep)")
      ->check(CLI::IsMember({"none", "azimuth"}))
      ->capture_default_str();
  add_common(kitti, o, central_position);

  CLI::App* sweeps =
      app.add_subcommand("sweeps", "a folder of .bin, .pcd or .ply sweeps with optional times and poses");
  std::string sweeps_dir;
  sim::SweepFolderOptions so;
  sweeps->add_option("folder", sweeps_dir, "folder of sweeps (name order)")->required()->check(CLI::ExistingDirectory);
  sweeps
      ->add_option("--times", so.times, "sweep times, seconds per line (default FOLDER/times.txt, else index x period)")
      ->check(CLI::ExistingFile);
  sweeps->add_option("--poses", so.poses, "the LiDAR's poses: KITTI 3x4 lines (one per sweep) or TUM (interpolated)")
      ->check(CLI::ExistingFile);
  sweeps->add_option("--poses-kind", so.poses_kind, "what the poses are: reference or ground_truth")
      ->check(CLI::IsMember({"reference", "ground_truth"}))
      ->capture_default_str();
  cdc::config::add_number_option(*sweeps, "--period", so.period_s, "sweep period [s] without a times file", 0.001, 10);
  add_common(sweeps, o, central_position);

  CLI::App* bag = app.add_subcommand("bag", "a ROS 1 bag or a ROS 2 bag (db3 folder or file, MCAP), read without ROS");
  std::string bag_path;
  sim::BagImportOptions bo;
  std::vector<double> T_lidar_imu;
  bag->add_option("bag", bag_path, "the .bag, .db3, .mcap file or the ROS 2 bag folder")
      ->required()
      ->check(CLI::ExistingPath);
  bag->add_option("--lidar-topic", bo.lidar_topic,
                  "sensor_msgs/PointCloud2 or velodyne_msgs/VelodyneScan topic (default: the only one)");
  bag->add_option("--imu-topic", bo.imu_topic, "sensor_msgs/Imu topic (default: the only one; none: ignore the IMU)");
  bag->add_option("--calibration", bo.velodyne_calibration,
                  "VelodyneScan: the sensor's calibration YAML (ROS driver format)")
      ->check(CLI::ExistingFile);
  bag->add_option("--model", bo.velodyne_model,
                  "VelodyneScan: VLP16, VLP32C, HDL32E, HDL64E (S2), HDL64E_S3 or VLS128 (default: from the packets)");
  cdc::config::add_number_option(*bag, "--scan-phase", bo.velodyne_scan_phase_deg,
                                 "VelodyneScan: azimuth [deg] where sweeps are cut", 0, 360);
  cdc::config::add_number_option(*bag, "--min-range", bo.min_range_m, "VelodyneScan: nearest return kept [m]", 0, 1000);
  cdc::config::add_number_option(*bag, "--max-range", bo.max_range_m, "VelodyneScan: farthest return kept [m]", 0.1,
                                 1000);
  bag->add_option("--T-lidar-imu", T_lidar_imu, "the IMU's pose in the LiDAR frame: x y z qx qy qz qw")
      ->expected(7)
      ->check(cdc::config::cli_range(-100, 100));
  std::string bag_poses;
  bag->add_option("--poses", bag_poses,
                  "reference or ground-truth poses of the LiDAR (TUM, interpolated at the sweeps)")
      ->check(CLI::ExistingFile);
  add_common(bag, o, central_position);

  CLI11_PARSE(app, argc, argv);
  return cdc::base::run_tool("cdc-import", [&] {
    if (!central_position.empty()) {
      o.radio.central_robot = -1;
      o.radio.central_position = Eigen::Vector3d(central_position[0], central_position[1], central_position[2]);
    }
    sim::Recording rec;
    if (kitti->parsed()) {
      ko.period_ns = static_cast<int64_t>(std::llround(kitti_period * 1e9));
      ko.poses_frame = poses_frame == "lidar" ? io::KittiPosesFrame::kLidar : io::KittiPosesFrame::kCamera;
      rec = sim::kitti_recording(
          kitti_dir, ko, point_times == "azimuth" ? io::PointTimes::kAzimuth : io::PointTimes::kNone, "ground_truth");
    } else if (sweeps->parsed()) {
      rec = sim::sweep_folder_recording(sweeps_dir, so);
    } else {
      if (!T_lidar_imu.empty()) {
        const Eigen::Quaterniond q(T_lidar_imu[6], T_lidar_imu[3], T_lidar_imu[4], T_lidar_imu[5]);
        if (std::abs(q.norm() - 1) > 1e-3)
          throw std::invalid_argument("--T-lidar-imu: the quaternion is not of unit length");
        bo.T_lidar_imu.linear() = q.normalized().toRotationMatrix();
        bo.T_lidar_imu.translation() = Eigen::Vector3d(T_lidar_imu[0], T_lidar_imu[1], T_lidar_imu[2]);
        bo.T_lidar_imu_given = true;
      }
      fs::path scratch = o.out;
      scratch += ".extract";
      rec = sim::bag_recording(bag_path, bo, scratch);
      if (!bag_poses.empty()) sim::attach_poses(rec, bag_poses, "reference");
    }
    const sim::ImportSummary sum = sim::write_import(rec, o);
    for (const std::string& n : sum.notes) std::cout << "cdc-import: " << n << '\n';
    std::cout << "cdc-import: wrote " << o.out.string() << ": " << sum.info.robots << " robot(s), " << sum.info.scans
              << " sweeps, " << sum.info.points << " points, point times " << io::to_string(sum.info.point_times)
              << ", radio " << sum.info.radio << " (" << sum.info.out_of_range_periods << " out-of-range periods)";
    if (sum.skipped > 0) std::cout << ", " << sum.skipped << " input items skipped";
    std::cout << '\n';
    return 0;
  });
}
