// The emulated radio of a launched swarm.
//
// netns: every node (each robot, the central node, the simulator) in a network namespace of its own,
// joined by veth pairs to a bridge in a hub namespace, addresses in 198.18.0.0/24. A link between
// two nodes goes out of range by iptables DROP rules in the robot's namespace on the SLAM domain's
// UDP ports (Cyclone maps domain d to ports 7400 + 250 d ... + 249), so DDS traffic, discovery and
// liveliness really stop while the simulator's domain (sensors, lock-step) stays up. Radio faults
// (random loss, one-way cuts) are rules of the same kind in a chain of their own. Accounting
// rules count the SLAM bytes each robot sends to and receives from every other node.
// Every namespace (and with it every link and rule) is deleted by teardown() or the destructor.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace cdc::launch {

inline constexpr uint32_t kCentralNode = 200;  // the central's node id (as in the radio timeline)
inline constexpr uint32_t kSimNode = 250;      // the simulator's namespace

// SLAM-domain UDP bytes (IP packets) seen by the robot's side of a link. Cyclone sends user data
// (samples, their heartbeats and acknowledgements) to odd port offsets and discovery (SPDP, SEDP,
// participant liveliness) to even ones, which tells the two apart.
struct LinkBytes {
  uint64_t sent = 0, received = 0;            // user data
  uint64_t meta_sent = 0, meta_received = 0;  // discovery
};

class NetnsNetwork {
 public:
  // nodes: robot ids plus kCentralNode and kSimNode. `tag` makes the namespace names unique.
  NetnsNetwork(const std::string& tag, const std::vector<uint32_t>& nodes, uint32_t slam_domain,
               const std::string& config_dir);
  ~NetnsNetwork();
  NetnsNetwork(const NetnsNetwork&) = delete;
  NetnsNetwork& operator=(const NetnsNetwork&) = delete;

  // Whether this process may create network namespaces (root, ip and iptables present).
  static bool available(std::string* why);

  const std::string& netns(uint32_t node) const { return netns_.at(node); }
  std::string address(uint32_t node) const;
  // file:// URI of the node's Cyclone DDS configuration (its veth, unicast peers = every node).
  std::string dds_config(uint32_t node) const { return "file://" + configs_.at(node); }
  // Cuts (up = false) or restores the SLAM traffic between two nodes (at least one a robot).
  void set_link(uint32_t a, uint32_t b, bool up);
  bool link_up(uint32_t a, uint32_t b) const;
  // Drops SLAM datagrams from src to dst with probability p (0: the fault rule is removed, 1: all),
  // in a fault chain of their own, applied before the range cuts and the accounting.
  void set_drop(uint32_t src, uint32_t dst, double p);
  double drop(uint32_t src, uint32_t dst) const;
  // SLAM datagrams the fault rules have dropped so far (rules removed since included).
  uint64_t fault_dropped() const;
  // Per robot and peer node: bytes counted so far.
  std::map<std::pair<uint32_t, uint32_t>, LinkBytes> counters() const;
  void teardown();
  std::vector<std::string> namespaces() const;

 private:
  void ns_cmd(uint32_t node, std::vector<std::string> argv) const;
  void create_namespaces();
  void write_dds_config(uint32_t node, const std::string& config_dir);
  void add_robot_rules(uint32_t node);
  void drop_rule(uint32_t src, uint32_t dst, const std::string& probability, const char* op) const;
  uint64_t fault_chain_drops(uint32_t node) const;
  struct RuleCount {
    uint64_t packets = 0, bytes = 0;
    std::string target, src, dst, line;
  };
  std::vector<RuleCount> list_chain(uint32_t node, const char* chain) const;
  std::string tag_;
  std::vector<uint32_t> nodes_;
  std::string hub_;
  std::map<uint32_t, std::string> netns_;
  std::map<uint32_t, std::string> configs_;
  std::string port_range_;
  std::map<std::pair<uint32_t, uint32_t>, bool> down_;
  std::map<std::pair<uint32_t, uint32_t>, std::string> drops_;  // (src, dst) -> probability in its rule
  uint64_t removed_rule_drops_ = 0;                             // what rules deleted by set_drop had dropped
  bool torn_down_ = false;
};

// Out-of-range periods of a dataset (radio_periods.csv: a,b,start,end in seconds of sim time).
struct RadioPeriod {
  uint32_t a = 0, b = 0;
  double start_s = 0, end_s = 0;
};
std::vector<RadioPeriod> read_radio_periods(const std::string& path);
// Whether the pair (a, b) is in range at sim time t.
bool in_range(const std::vector<RadioPeriod>& periods, uint32_t a, uint32_t b, double t_s);

}  // namespace cdc::launch
