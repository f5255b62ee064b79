#include "network.hpp"

#include "process.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace cdc::launch {
namespace {

bool is_robot(uint32_t node) { return node != kCentralNode && node != kSimNode; }

std::string short_name(uint32_t node) {
  if (node == kCentralNode) return "c";
  if (node == kSimNode) return "s";
  std::string s = "r";  // appended: GCC 12 warns falsely (-Wrestrict) on "r" + std::to_string(...)
  s += std::to_string(node);
  return s;
}

}  // namespace

bool NetnsNetwork::available(std::string* why) {
  auto fail = [&](const std::string& w) {
    if (why) *why = w;
    return false;
  };
  if (geteuid() != 0) return fail("not root");
  if (run_command({"ip", "-V"}).status != 0) return fail("iproute2's ip is missing");
  if (run_command({"iptables", "--version"}).status != 0) return fail("iptables is missing");
  const std::string probe = "cdc-probe-" + std::to_string(getpid());
  if (run_command({"ip", "netns", "add", probe}).status != 0) return fail("'ip netns add' is not permitted here");
  run_command({"ip", "netns", "delete", probe});
  return true;
}

std::string NetnsNetwork::address(uint32_t node) const {
  if (node == kCentralNode) return "198.18.0.100";
  if (node == kSimNode) return "198.18.0.200";
  if (node >= 90)
    throw std::invalid_argument("robot id " + std::to_string(node) + ": netns mode supports ids below 90");
  return "198.18.0." + std::to_string(10 + node);
}

void NetnsNetwork::ns_cmd(uint32_t node, std::vector<std::string> argv) const {
  argv.insert(argv.begin(), {"ip", "netns", "exec", netns_.at(node)});
  run_checked(argv);
}

NetnsNetwork::NetnsNetwork(const std::string& tag, const std::vector<uint32_t>& nodes, uint32_t slam_domain,
                           const std::string& config_dir)
    : tag_(tag), nodes_(nodes), hub_("cdc" + tag + "-hub") {
  const uint32_t base = 7400 + 250 * slam_domain;
  port_range_ = std::to_string(base) + ":" + std::to_string(base + 249);
  try {
    create_namespaces();
    for (uint32_t node : nodes_) write_dds_config(node, config_dir);
    for (uint32_t node : nodes_) {
      if (is_robot(node)) add_robot_rules(node);
    }
  } catch (...) {
    teardown();
    throw;
  }
}

// The hub's bridge, and per node a namespace joined to it by a veth pair (eth0 inside, with the
// node's address).
void NetnsNetwork::create_namespaces() {
  run_checked({"ip", "netns", "add", hub_});
  run_checked({"ip", "-n", hub_, "link", "add", "br0", "type", "bridge"});
  run_checked({"ip", "-n", hub_, "link", "set", "br0", "up"});
  for (uint32_t node : nodes_) {
    const std::string ns = "cdc" + tag_ + "-" + short_name(node);
    run_checked({"ip", "netns", "add", ns});
    netns_[node] = ns;
    std::string hub_end = "h";
    hub_end += short_name(node);
    run_checked({"ip", "-n", hub_, "link", "add", hub_end, "type", "veth", "peer", "name", "eth0", "netns", ns});
    run_checked({"ip", "-n", hub_, "link", "set", hub_end, "master", "br0", "up"});
    run_checked({"ip", "-n", ns, "addr", "add", address(node) + "/24", "dev", "eth0"});
    run_checked({"ip", "-n", ns, "link", "set", "eth0", "up"});
    run_checked({"ip", "-n", ns, "link", "set", "lo", "up"});
  }
}

// DDS of one node: its veth, unicast discovery of every node, no multicast.
void NetnsNetwork::write_dds_config(uint32_t node, const std::string& config_dir) {
  std::string peers;
  for (uint32_t n : nodes_) peers += "        <Peer Address=\"" + address(n) + "\"/>\n";
  const std::string path = config_dir + "/" + short_name(node) + ".xml";
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
         "<!-- written by cdc-launch: node "
      << short_name(node) << " in namespace " << netns_[node]
      << " -->\n"
         "<CycloneDDS xmlns=\"https://cdds.io/config\">\n  <Domain Id=\"any\">\n    <General>\n"
         "      <Interfaces><NetworkInterface name=\"eth0\"/></Interfaces>\n"
         "      <AllowMulticast>false</AllowMulticast>\n"
         // Datagrams within a 1500-byte MTU: large samples go as DDSI fragments rather than IP
         // fragments, as on a real radio, and every byte passes the per-port radio and accounting rules.
         "      <MaxMessageSize>1456B</MaxMessageSize>\n      <FragmentSize>1344B</FragmentSize>\n"
         "    </General>\n    <Discovery>\n"
         // At most 4 participants per node and domain (a robot's four services in the SLAM domain);
         // unicast discovery probes every index up to this on every peer, so keep it small.
         "      <ParticipantIndex>auto</ParticipantIndex>\n      <MaxAutoParticipantIndex>9</MaxAutoParticipantIndex>\n"
         "      <SPDPInterval>1s</SPDPInterval>\n"
         "      <Peers>\n"
      << peers << "      </Peers>\n    </Discovery>\n  </Domain>\n</CycloneDDS>\n";
  configs_[node] = path;
}

// A robot's chains: the faults' (set_drop) and the radio's (drops, filled by set_link) before the accounting's (what
// really passed), with one counting rule per peer, direction and kind of traffic.
void NetnsNetwork::add_robot_rules(uint32_t node) {
  for (const char* chain :
       {"CDC_FAULT_IN", "CDC_FAULT_OUT", "CDC_RADIO_IN", "CDC_RADIO_OUT", "CDC_ACCT_IN", "CDC_ACCT_OUT"}) {
    ns_cmd(node, {"iptables", "-w", "-N", chain});
  }
  ns_cmd(node, {"iptables", "-w", "-A", "INPUT", "-j", "CDC_FAULT_IN"});
  ns_cmd(node, {"iptables", "-w", "-A", "OUTPUT", "-j", "CDC_FAULT_OUT"});
  ns_cmd(node, {"iptables", "-w", "-A", "INPUT", "-j", "CDC_RADIO_IN"});
  ns_cmd(node, {"iptables", "-w", "-A", "INPUT", "-j", "CDC_ACCT_IN"});
  ns_cmd(node, {"iptables", "-w", "-A", "OUTPUT", "-j", "CDC_RADIO_OUT"});
  ns_cmd(node, {"iptables", "-w", "-A", "OUTPUT", "-j", "CDC_ACCT_OUT"});
  for (uint32_t peer : nodes_) {
    if (peer == node || peer == kSimNode) continue;
    for (const char* kind : {"data", "meta"}) {
      // Lowest bit of the UDP destination port: 1 for user data, 0 for discovery.
      const std::string parity = std::string("0>>22&0x3C@0&0x1=") + (std::string(kind) == "data" ? "1" : "0");
      ns_cmd(node, {"iptables", "-w",      "-A",        "CDC_ACCT_IN", "-s",  address(peer), "-p",
                    "udp",      "--dport", port_range_, "-m",          "u32", "--u32",       parity,
                    "-m",       "comment", "--comment", kind,          "-j",  "RETURN"});
      ns_cmd(node, {"iptables", "-w",      "-A",        "CDC_ACCT_OUT", "-d",  address(peer), "-p",
                    "udp",      "--dport", port_range_, "-m",           "u32", "--u32",       parity,
                    "-m",       "comment", "--comment", kind,           "-j",  "RETURN"});
    }
  }
}

NetnsNetwork::~NetnsNetwork() { teardown(); }

std::vector<std::string> NetnsNetwork::namespaces() const {
  std::vector<std::string> out{hub_};
  for (const auto& [node, ns] : netns_) out.push_back(ns);
  return out;
}

void NetnsNetwork::teardown() {
  if (torn_down_) return;
  torn_down_ = true;
  // Deleting a namespace deletes its veth ends (and so the peers in the hub) and its rules.
  for (const auto& [node, ns] : netns_) run_command({"ip", "netns", "delete", ns});
  run_command({"ip", "netns", "delete", hub_});
}

bool NetnsNetwork::link_up(uint32_t a, uint32_t b) const {
  auto it = down_.find({std::min(a, b), std::max(a, b)});
  return it == down_.end() || !it->second;
}

void NetnsNetwork::set_link(uint32_t a, uint32_t b, bool up) {
  if (link_up(a, b) == up) return;
  if (!netns_.count(a) || !netns_.count(b)) return;  // a node this swarm does not run
  const char* op = up ? "-D" : "-A";
  for (auto [me, other] : {std::pair{a, b}, std::pair{b, a}}) {
    if (!is_robot(me)) continue;
    ns_cmd(me, {"iptables", "-w", op, "CDC_RADIO_IN", "-s", address(other), "-p", "udp", "--dport", port_range_, "-j",
                "DROP"});
    ns_cmd(me, {"iptables", "-w", op, "CDC_RADIO_OUT", "-d", address(other), "-p", "udp", "--dport", port_range_, "-j",
                "DROP"});
  }
  down_[{std::min(a, b), std::max(a, b)}] = !up;
}

// One rule per directed pair, in the receiver's input chain when it is a robot, else in the
// sender's output chain (the central's namespace holds no rules).
void NetnsNetwork::drop_rule(uint32_t src, uint32_t dst, const std::string& probability, const char* op) const {
  const bool in = is_robot(dst);
  std::vector<std::string> argv{"iptables",
                                "-w",
                                op,
                                in ? "CDC_FAULT_IN" : "CDC_FAULT_OUT",
                                in ? "-s" : "-d",
                                address(in ? src : dst),
                                "-p",
                                "udp",
                                "--dport",
                                port_range_};
  if (probability != "1") {
    for (const char* a : {"-m", "statistic", "--mode", "random", "--probability"}) argv.emplace_back(a);
    argv.push_back(probability);
  }
  for (const char* a : {"-j", "DROP"}) argv.emplace_back(a);
  ns_cmd(in ? dst : src, argv);
}

void NetnsNetwork::set_drop(uint32_t src, uint32_t dst, double p) {
  if (!netns_.count(src) || !netns_.count(dst) || (!is_robot(src) && !is_robot(dst))) return;
  char text[32];
  std::snprintf(text, sizeof text, "%.4f", std::clamp(p, 0.0, 1.0));
  std::string probability = p >= 1.0 ? "1" : p <= 0.0 ? "" : text;
  auto it = drops_.find({src, dst});
  const std::string current = it == drops_.end() ? "" : it->second;
  if (current == probability) return;
  if (!current.empty()) {
    const uint32_t holder = is_robot(dst) ? dst : src;
    const uint64_t before = fault_chain_drops(holder);
    drop_rule(src, dst, current, "-D");
    removed_rule_drops_ += before - std::min(before, fault_chain_drops(holder));
  }
  if (!probability.empty()) drop_rule(src, dst, probability, "-A");
  if (probability.empty()) {
    drops_.erase({src, dst});
  } else {
    drops_[{src, dst}] = probability;
  }
}

// The rules of one of the node's chains with their counters (iptables -n -v -x -L), in order; empty when
// the chain cannot be listed.
std::vector<NetnsNetwork::RuleCount> NetnsNetwork::list_chain(uint32_t node, const char* chain) const {
  std::vector<RuleCount> out;
  const CommandResult r =
      run_command({"ip", "netns", "exec", netns_.at(node), "iptables", "-w", "-n", "-v", "-x", "-L", chain});
  if (r.status != 0) return out;
  std::istringstream in(r.output);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string pkts, bytes, prot, opt, iface_in, iface_out;
    RuleCount rule;
    if (!(f >> pkts >> bytes >> rule.target >> prot >> opt >> iface_in >> iface_out >> rule.src >> rule.dst)) continue;
    if (pkts.find_first_not_of("0123456789") != std::string::npos) continue;  // the column headings
    rule.packets = std::stoull(pkts);
    rule.bytes = std::stoull(bytes);
    rule.line = line;
    out.push_back(std::move(rule));
  }
  return out;
}

// Packets dropped by the fault rules now in the node's two fault chains.
uint64_t NetnsNetwork::fault_chain_drops(uint32_t node) const {
  uint64_t sum = 0;
  for (const char* chain : {"CDC_FAULT_IN", "CDC_FAULT_OUT"}) {
    for (const RuleCount& rule : list_chain(node, chain)) {
      if (rule.target == "DROP") sum += rule.packets;
    }
  }
  return sum;
}

uint64_t NetnsNetwork::fault_dropped() const {
  uint64_t sum = removed_rule_drops_;
  for (uint32_t node : nodes_) {
    if (is_robot(node)) sum += fault_chain_drops(node);
  }
  return sum;
}

double NetnsNetwork::drop(uint32_t src, uint32_t dst) const {
  auto it = drops_.find({src, dst});
  return it == drops_.end() ? 0.0 : std::stod(it->second);
}

std::map<std::pair<uint32_t, uint32_t>, LinkBytes> NetnsNetwork::counters() const {
  std::map<std::pair<uint32_t, uint32_t>, LinkBytes> out;
  std::map<std::string, uint32_t> by_address;
  for (uint32_t n : nodes_) by_address[address(n)] = n;
  for (uint32_t node : nodes_) {
    if (!is_robot(node)) continue;
    for (const char* chain : {"CDC_ACCT_IN", "CDC_ACCT_OUT"}) {
      const bool incoming = std::string(chain) == "CDC_ACCT_IN";
      for (const RuleCount& rule : list_chain(node, chain)) {
        if (rule.target != "RETURN") continue;
        auto it = by_address.find(incoming ? rule.src : rule.dst);
        if (it == by_address.end()) continue;
        LinkBytes& lb = out[{node, it->second}];
        if (rule.line.find("/* meta */") != std::string::npos) {
          (incoming ? lb.meta_received : lb.meta_sent) = rule.bytes;
        } else {
          (incoming ? lb.received : lb.sent) = rule.bytes;
        }
      }
    }
  }
  return out;
}

std::vector<RadioPeriod> read_radio_periods(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot read the radio periods");
  std::vector<RadioPeriod> out;
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (n == 1 || line.empty()) continue;  // header a,b,start,end
    RadioPeriod p;
    if (std::sscanf(line.c_str(), "%u,%u,%lf,%lf", &p.a, &p.b, &p.start_s, &p.end_s) != 4 || p.end_s < p.start_s) {
      throw std::runtime_error(path + ":" + std::to_string(n) + ": expected a,b,start,end with start <= end");
    }
    out.push_back(p);
  }
  return out;
}

bool in_range(const std::vector<RadioPeriod>& periods, uint32_t a, uint32_t b, double t_s) {
  for (const RadioPeriod& p : periods) {
    if (((p.a == a && p.b == b) || (p.a == b && p.b == a)) && t_s >= p.start_s && t_s < p.end_s) return false;
  }
  return true;
}

}  // namespace cdc::launch
