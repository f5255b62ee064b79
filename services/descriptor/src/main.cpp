// cdc-descriptor: a robot's keyframes in, their Scan Context descriptors out. Only descriptors
// (about 0.6 KB each, packed) leave the robot by default; clouds stay home until a peer asks for
// one. Descriptors are sent once, live; a robot that missed some (out of range, or not matched
// yet) asks for the missing range on cdc/place/descriptor_sync and gets just those again.
#include "cdc/config/reader.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/traffic_json.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/dds_lidar/descriptor_convert.hpp"
#include "cdc/lidar/scan_context.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <set>

namespace {

using namespace cdc;

struct Options {
  uint32_t robot = 0, robots = 3, domain = 0;
  int local_domain = -1;  // the robot's own domain (keyframes in, its own descriptors out); -1: none
  std::string dds_config, local_dds_config, stats_out, log_level = "info";
  lidar::ScanContextParams sc;
  uint32_t max_per_sync = 256;  // descriptors sent for one sync request (the requester asks again for more)
};

// A published descriptor, kept to answer sync requests: msg's sequences borrow the vectors below
// (a map node never moves, so they stay valid).
struct Stored {
  cdc_msg_Descriptor msg{};
  std::vector<uint8_t> packed_cells;
};

void load(const std::string& path, Options& o) {
  config::Reader r(path);
  int robots = static_cast<int>(o.robots);
  r.get<int>("robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.robots = static_cast<uint32_t>(robots);
  r.get<int>("scan_context.rings", o.sc.rings, [](const int& v) { return v >= 1 && v <= 255; }, "1..255");
  r.get<int>("scan_context.sectors", o.sc.sectors, [](const int& v) { return v >= 4 && v <= 255; }, "4..255");
  r.get<double>("scan_context.max_range_m", o.sc.max_range_m, [](const double& v) { return v > 0; }, "> 0");
  r.get<double>("scan_context.sensor_height_m", o.sc.sensor_height_m, [](const double& v) { return v >= 0; }, ">= 0");
  int per_sync = static_cast<int>(o.max_per_sync);
  r.get<int>("max_per_sync", per_sync, [](const int& v) { return v >= 1 && v <= 100000; }, "1..100000");
  o.max_per_sync = static_cast<uint32_t>(per_sync);
  r.get<std::string>("log_level", o.log_level);
  r.finish();
}

int run(const Options& o) {
  dds::ParticipantOptions po;
  po.domain_id = o.domain;
  po.config = o.dds_config;
  dds::RobotDomains domains(po, dds::local_domain_options(o.local_domain, o.local_dds_config, po), runtime::log_radio_switch);
  const dds::Participant& participant = domains.radio();
  const dds::Participant& local = domains.local();
  dds::Topic<cdc_msg_Keyframe> t_kf(local, dds::topics::kKeyframe);
  dds::Topic<cdc_msg_Descriptor> t_desc(participant, dds::topics::kDescriptor);
  dds::Topic<cdc_msg_DescriptorSync> t_sync(participant, dds::topics::kDescriptorSync);
  dds::Reader<cdc_msg_Keyframe> r_kf(local, t_kf, dds::qos::event_stream(4096).partitions(dds::partitions::own_reader(o.robot)));
  // On a local domain of its own the robot's loop closure gets its descriptors there too, also
  // while the radio is cut.
  std::optional<dds::Topic<cdc_msg_Descriptor>> t_desc_local;
  std::optional<dds::Writer<cdc_msg_Descriptor>> w_desc_local;
  if (domains.split()) {
    t_desc_local.emplace(local, dds::topics::kDescriptor);
    w_desc_local.emplace(local, *t_desc_local, dds::qos::event_stream(256));
  }
  // Live descriptors are volatile: whoever missed some asks for them (cdc/place/descriptor_sync),
  // and gets them from a writer in its own partition. A transient-local history would instead
  // replay every descriptor ever made to each peer on every reconnection.
  dds::Writer<cdc_msg_Descriptor> w_desc(participant, t_desc, dds::qos::event_stream(256));
  dds::Reader<cdc_msg_DescriptorSync> r_sync(participant, t_sync, dds::qos::event_stream(256));
  dds::PerRobotWriters<cdc_msg_Descriptor> w_resend(participant, t_desc,
                                                    dds::qos::event_stream(static_cast<int32_t>(o.max_per_sync)), o.robots);
  dds::GuardCondition stop;
  dds::ShutdownSignal::add_guard(&stop);
  dds::ReadCondition rc_kf(r_kf.handle()), rc_sync(r_sync.handle());
  dds::WaitSet ws;  // conditions of both domains
  ws.attach(stop.handle(), 0);
  ws.attach(rc_kf.handle(), 1);
  ws.attach(rc_sync.handle(), 2);
  dds::ValidationLimits limits;
  limits.robot_count = o.robots;
  dds::RejectionCounter rejected;
  uint64_t published = 0, bytes = 0, repeated = 0, syncs = 0, resent = 0, resent_bytes = 0;
  std::map<uint32_t, Stored> store;  // this incarnation's descriptors by keyframe id
  uint32_t incarnation = 0;
  // Keyframes the peer optimiser re-sends to a central that lacks them come here too: each
  // (incarnation, keyframe) is described once (peers that missed it ask for it).
  std::set<std::pair<uint32_t, uint32_t>> described;
  std::vector<Eigen::Vector3f> points;
  std::vector<uint8_t> cells;
  spdlog::info("descriptor service of robot {} up: Scan Context {}x{} to {} m, domain {}{}", o.robot, o.sc.rings,
               o.sc.sectors, o.sc.max_range_m, o.domain,
               domains.split() ? ", own keyframes on local domain " + std::to_string(o.local_domain) : std::string());
  while (!dds::ShutdownSignal::requested()) {
    ws.wait(std::chrono::milliseconds(200));
    r_sync.take(64).for_each_valid([&](const cdc_msg_DescriptorSync& m, const dds_sample_info_t&) {
      if (m.owner_robot_id != o.robot) {
        return;
      }
      if (rejected.record(dds::topics::kDescriptorSync, dds::validate(m, limits))) {
        spdlog::warn("rejected descriptor sync: {}", rejected.last_reason());
        return;
      }
      ++syncs;
      dds::Writer<cdc_msg_Descriptor>* to = w_resend.to(m.requester_robot_id);
      if (to == nullptr) return;  // validated above: a robot of the swarm
      uint32_t n = 0;
      for (auto it = store.lower_bound(m.first_keyframe_id);
           it != store.end() && it->first <= m.last_keyframe_id && n < o.max_per_sync; ++it, ++n) {
        to->write(it->second.msg);
        ++resent;
        resent_bytes += dds::serialized_size(it->second.msg);
      }
      spdlog::debug("robot {} asked for descriptors {}..{}: {} sent", m.requester_robot_id, m.first_keyframe_id,
                    m.last_keyframe_id, n);
    });
    r_kf.take(64).for_each_valid([&](const cdc_msg_Keyframe& m, const dds_sample_info_t&) {
      if (m.robot_id != o.robot) {
        return;
      }
      if (rejected.record(dds::topics::kKeyframe, dds::validate(m, limits))) {
        spdlog::warn("rejected keyframe: {}", rejected.last_reason());
        return;
      }
      if (!described.insert({m.incarnation, m.keyframe_id}).second) {
        ++repeated;
        return;
      }
      points.clear();
      for (uint32_t i = 0; i < m.cloud._length; ++i) {
        points.emplace_back(m.cloud._buffer[i].x, m.cloud._buffer[i].y, m.cloud._buffer[i].z);
      }
      const lidar::QuantizedScanContext q = lidar::quantize(lidar::make_scan_context(points, o.sc));
      cdc_msg_Descriptor d{};
      d.robot_id = m.robot_id;
      d.keyframe_id = m.keyframe_id;
      d.incarnation = m.incarnation;
      d.stamp_ns = m.stamp_ns;
      d.pose_hint = dds::to_msg_f(dds::to_eigen(m.T_odom_keyframe));
      dds_lidar::descriptor_to_msg(q, static_cast<float>(o.sc.max_range_m), d, cells);
      w_desc.write(d);
      if (w_desc_local) w_desc_local->write(d);
      ++published;
      bytes += dds::serialized_size(d);
      if (m.incarnation != incarnation) {  // a restarted front-end numbers its keyframes afresh
        store.clear();
        incarnation = m.incarnation;
      }
      Stored& st = store[m.keyframe_id];
      st.msg = d;
      st.packed_cells = cells;
      dds::borrow(st.msg.packed_cells, st.packed_cells);
    });
  }
  dds::ShutdownSignal::remove_guard(&stop);
  if (!o.stats_out.empty()) {
    nlohmann::json j{{"robot", o.robot},
                     {"descriptors", published},
                     {"repeated_keyframes", repeated},
                     {"first_send_bytes", bytes},  // every write, re-sends too: "topics"
                     {"sync_requests", syncs},
                     {"resent", resent},
                     {"resent_bytes", resent_bytes},
                     {"bytes_per_descriptor", published > 0 ? static_cast<double>(bytes) / static_cast<double>(published) : 0.0},
                     {"radio_cuts", domains.radio_cuts()},
                     {"rejected", rejected.by_topic()},
                     {"rejected_samples", rejected.total()}};
    j["topics"] = dds::topic_traffic_json();
    std::ofstream(o.stats_out) << j.dump(2) << '\n';
  }
  spdlog::info("stopped after {} descriptors ({} bytes)", published, bytes);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  dds::ShutdownSignal::install();
  CLI::App app{
      "cdc-descriptor: computes a Scan Context descriptor (quantised to one byte per cell) for every keyframe of\n"
      "this robot and publishes it with the keyframe's pose hint. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2\n"
      "cut and restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio."};
  Options o;
  std::string config_path, log_level;
  int domain = -1;
  app.add_option("--robot", o.robot, "this robot's id")->required()->check(CLI::Range(0, 254));
  app.add_option("--config", config_path, "YAML configuration (see services/descriptor/config)")->check(CLI::ExistingFile);
  app.add_option("--dds-config", o.dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--local-domain", o.local_domain,
                 "the robot's own DDS domain (keyframes in; its descriptors also out there); default: none, all on --domain")
      ->check(CLI::Range(0, 232));
  app.add_option("--local-dds-config", o.local_dds_config, "Cyclone DDS configuration of the local domain (default: as --dds-config)");
  app.add_option("--stats-out", o.stats_out, "write counters (JSON) here at shutdown");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  try {
    load(config_path, o);
    if (o.robot >= o.robots) {
      std::cerr << "cdc-descriptor: --robot " << o.robot << " is not one of the " << o.robots
                << " robots of the configuration\n";
      return 2;
    }
    o.domain = domain >= 0 ? static_cast<uint32_t>(domain) : dds::domain_from_env(0);
    if (!log_level.empty()) o.log_level = log_level;
    runtime::init_logging("cdc-descriptor-" + std::to_string(o.robot), o.log_level);
    return run(o);
  } catch (const config::ConfigError& e) {
    std::cerr << "cdc-descriptor: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cdc-descriptor: " << e.what() << '\n';
    return 1;
  }
}
