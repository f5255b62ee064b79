// cdc-velodyne-pcap: Velodyne packets between ROS bags, pcap captures and sweeps on disk.
//   bag2pcap BAG OUT.pcap   the bag's velodyne_msgs/VelodyneScan packets as UDP datagrams to
//                           127.0.0.1:PORT, stamped with the packets' own stamps
//   decode IN.pcap          the capture's datagrams on PORT assembled into sweeps; with --out, each sweep
//                           as OUT/velodyne/NNNNNN.bin (KITTI: float32 x, y, z, intensity), per-point time
//                           offset and ring in OUT/velodyne_meta/NNNNNN.bin, and OUT/times.txt (sweep
//                           stamps [ns]); prints the counts.
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/io/bag.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/pcap.hpp"
#include "cdc/io/ros_messages.hpp"
#include "cdc/io/velodyne.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using namespace cdc::io;

int bag_to_pcap(const std::string& bag_path, const std::string& out_path, const std::string& topic, uint16_t port) {
  auto bag = open_bag(bag_path);
  PcapWriter writer(out_path);
  BagMessage m;
  uint64_t messages = 0, packets = 0;
  while (bag->next(m)) {
    if (m.type != "velodyne_msgs/msg/VelodyneScan" || (!topic.empty() && m.topic != topic)) continue;
    const VelodyneScanMsg scan = decode_velodyne_scan(m);
    ++messages;
    for (const auto& p : scan.packets) {
      UdpDatagram d;
      d.stamp_ns = p.stamp_ns;
      d.src_ip = d.dst_ip = 0x7F000001;  // 127.0.0.1
      d.src_port = d.dst_port = port;
      d.payload.assign(p.data.begin(), p.data.end());
      writer.write(d);
      ++packets;
    }
  }
  writer.close();
  std::printf("{\"messages\": %llu, \"packets\": %llu, \"pcap\": \"%s\"}\n", static_cast<unsigned long long>(messages),
              static_cast<unsigned long long>(packets), out_path.c_str());
  if (messages == 0) {
    std::cerr << "cdc-velodyne-pcap: no VelodyneScan messages" << (topic.empty() ? "" : " on " + topic) << " in "
              << bag_path << "\n";
    return 1;
  }
  return 0;
}

struct DecodeArgs {
  std::string pcap, calibration, model, out, return_mode;
  uint16_t port = 2368;
  VelodyneDecoderOptions decoder;
  VelodyneSweepOptions sweep;
  bool keep_incomplete = false;
};

// Writes sweeps as OUT/velodyne/NNNNNN.bin, OUT/velodyne_meta/NNNNNN.bin and a line of OUT/times.txt each;
// without a folder it only counts them.
class SweepFiles {
 public:
  explicit SweepFiles(const std::string& out) : out_(out) {
    if (out_.empty()) return;
    std::filesystem::create_directories(out_ / "velodyne");
    std::filesystem::create_directories(out_ / "velodyne_meta");
    times_.open(out_ / "times.txt");
    if (!times_) throw std::runtime_error(out + "/times.txt: cannot be written");
  }

  void write(const VelodyneSweep& s) {
    if (out_.empty()) return;
    std::vector<CloudPoint> points;
    points.reserve(s.points.size());
    for (const auto& p : s.points) {
      CloudPoint c;
      c.x = p.x;
      c.y = p.y;
      c.z = p.z;
      c.intensity = p.intensity;
      c.time_offset = static_cast<float>(s.time_offset_s(p));
      c.ring = p.ring;
      points.push_back(c);
    }
    char name[32];
    std::snprintf(name, sizeof(name), "%06llu.bin", static_cast<unsigned long long>(written_));
    write_kitti_bin(out_ / "velodyne" / name, points);
    write_point_meta(out_ / "velodyne_meta" / name, points);
    times_ << s.stamp_ns << "\n";
    ++written_;
  }

  uint64_t written() const { return written_; }

 private:
  std::filesystem::path out_;
  std::ofstream times_;
  uint64_t written_ = 0;
};

void print_counts(const PcapStats& p, uint64_t other_ports, const VelodyneSweepAssembler& assembler, uint64_t written) {
  const VelodyneSweepStats& s = assembler.stats();
  const auto model = assembler.decoder().model();
  std::printf(
      "{\"records\": %llu, \"datagrams\": %llu, \"other_ports\": %llu, \"packets\": %llu, \"decoded\": %llu, "
      "\"truncated\": %llu, \"malformed\": %llu, \"out_of_order\": %llu, \"gaps\": %llu, \"sweeps\": %llu, "
      "\"incomplete_sweeps\": %llu, \"points\": %llu, \"written\": %llu, \"model\": \"%s\"}\n",
      static_cast<unsigned long long>(p.records), static_cast<unsigned long long>(p.datagrams),
      static_cast<unsigned long long>(other_ports), static_cast<unsigned long long>(s.packets),
      static_cast<unsigned long long>(s.decoded), static_cast<unsigned long long>(s.truncated),
      static_cast<unsigned long long>(s.malformed), static_cast<unsigned long long>(s.out_of_order),
      static_cast<unsigned long long>(s.gaps), static_cast<unsigned long long>(s.sweeps),
      static_cast<unsigned long long>(s.incomplete_sweeps), static_cast<unsigned long long>(s.points),
      static_cast<unsigned long long>(written), model ? std::string(to_string(*model)).c_str() : "unknown");
}

int decode(DecodeArgs& a) {
  std::optional<VelodyneModel> model;
  if (!a.model.empty()) model = velodyne_model_from_string(a.model);
  a.decoder.model = model;
  if (a.return_mode == "strongest") a.decoder.return_mode = VelodyneReturnMode::kStrongest;
  if (a.return_mode == "last") a.decoder.return_mode = VelodyneReturnMode::kLast;
  if (a.return_mode == "dual") a.decoder.return_mode = VelodyneReturnMode::kDual;
  a.sweep.emit_incomplete = a.keep_incomplete;
  const VelodyneCalibration cal = a.calibration.empty() ? default_velodyne_calibration(model.value())
                                                        : read_velodyne_calibration(a.calibration, model);
  VelodyneSweepAssembler assembler(cal, a.decoder, a.sweep);
  SweepFiles files(a.out);
  auto drain = [&]() {
    while (assembler.has_sweep()) files.write(assembler.take());
  };
  PcapReader reader(a.pcap);
  UdpDatagram d;
  uint64_t other_ports = 0;
  std::string error;
  try {
    while (reader.next(d)) {
      if (d.dst_port != a.port) {
        ++other_ports;
        continue;
      }
      assembler.add_packet(d.payload, d.stamp_ns);
      drain();
    }
  } catch (const FormatError& e) {
    error = e.what();  // a capture cut short: keep what was read, report it
  }
  assembler.flush();
  drain();
  print_counts(reader.stats(), other_ports, assembler, files.written());
  if (!error.empty()) {
    std::cerr << "cdc-velodyne-pcap: " << error << "\n";
    return 2;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cdc-velodyne-pcap: Velodyne packets between ROS bags, pcap captures and sweeps on disk."};
  app.require_subcommand(1);

  std::string bag, out_pcap, topic;
  uint16_t bag_port = 2368;
  CLI::App* b2p =
      app.add_subcommand("bag2pcap",
                         "write a bag's velodyne_msgs/VelodyneScan packets as UDP datagrams to 127.0.0.1:PORT (pcap, "
                         "nanosecond stamps: the packets' own)");
  b2p->add_option("bag", bag, "ROS 1 .bag, ROS 2 .db3 / .mcap or a ROS 2 bag folder")->required();
  b2p->add_option("out", out_pcap, "the pcap file to write")->required();
  b2p->add_option("--topic", topic, "only this topic (default: every VelodyneScan topic)");
  cdc::config::add_number_option(*b2p, "--port", bag_port, "UDP port of the datagrams", 1, 65535);

  DecodeArgs d;
  CLI::App* dec = app.add_subcommand(
      "decode",
      "assemble the capture's Velodyne datagrams into sweeps; print counts, and with --out write each sweep "
      "as OUT/velodyne/NNNNNN.bin (KITTI), OUT/velodyne_meta/NNNNNN.bin (float32 time offset [s], uint16 "
      "ring, uint16 0 per point) and OUT/times.txt (sweep stamps [ns])");
  dec->add_option("pcap", d.pcap, "the capture")->required()->check(CLI::ExistingFile);
  dec->add_option("--calibration", d.calibration,
                  "calibration YAML (ROS driver format); without it the built-in table of --model")
      ->check(CLI::ExistingFile);
  dec->add_option("--model", d.model,
                  "VLP16, VLP32C, HDL32E, HDL64E (S2, S2.1), HDL64E_S3 or VLS128 (default: from each packet)");
  dec->add_option("--out", d.out, "folder for the sweeps");
  cdc::config::add_number_option(*dec, "--port", d.port, "UDP destination port of the data packets", 1, 65535);
  dec->add_option("--return-mode", d.return_mode, "strongest, last or dual (default: from each packet)")
      ->check(CLI::IsMember({"strongest", "last", "dual"}));
  cdc::config::add_number_option(*dec, "--min-range", d.decoder.min_range, "[m]", 0, 1000);
  cdc::config::add_number_option(*dec, "--max-range", d.decoder.max_range, "[m]", 0.1, 1000);
  cdc::config::add_number_option(*dec, "--sector-min", d.decoder.sector_min_deg, "keep azimuths in [min, max] [deg]", 0,
                                 360);
  cdc::config::add_number_option(*dec, "--sector-max", d.decoder.sector_max_deg,
                                 "(wraps through 0 when min > max) [deg]", 0, 360);
  cdc::config::add_number_option(*dec, "--scan-phase", d.sweep.scan_phase_deg, "azimuth where sweeps are cut [deg]", 0,
                                 360);
  dec->add_flag("--keep-incomplete", d.keep_incomplete, "also write sweeps ended by a gap or the end of the capture");
  CLI11_PARSE(app, argc, argv);

  return cdc::base::run_tool("cdc-velodyne-pcap", [&] {
    if (b2p->parsed()) return bag_to_pcap(bag, out_pcap, topic, bag_port);
    if (d.model.empty() && d.calibration.empty()) {
      std::cerr << "cdc-velodyne-pcap decode: give --calibration or --model (for the built-in table)\n";
      return 1;
    }
    return decode(d);
  });
}
