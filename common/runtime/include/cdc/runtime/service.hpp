// What a service node stands on: its DDS domains, one waitset with the shutdown guard, and the
// boundary that validates, counts and logs every sample it refuses.
#pragma once

#include "cdc/dds/participant.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/runtime/options.hpp"

#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cdc::runtime {

// Validation at a node's boundary: a refused sample is counted by topic and logged with its reason,
// at most one line per topic and kind of reason (the reason with its numbers left out) per log period:
// a flood of bad samples is not a flood of log lines (the next line says how many went unlogged), and
// a sample refused for another reason is still named at once. At most kMaxLogGates kinds are told
// apart; past that, refusals share one gate per topic.
class Boundary {
 public:
  static constexpr std::chrono::milliseconds kLogPeriod{1000};
  static constexpr size_t kMaxLogGates = 256;

  explicit Boundary(dds::ValidationLimits limits) : limits_(std::move(limits)) {}
  const dds::ValidationLimits& limits() const noexcept { return limits_; }
  // Counts v when it refuses a sample of `topic`, and logs it unless its kind's log line is due later;
  // true when it refused. Returns whether it logged in *logged when given.
  bool refuse(std::string_view topic, const dds::Validation& v, bool* logged = nullptr);
  // The sample passes dds::validate.
  template <class Msg>
  bool admit(std::string_view topic, const Msg& m) {
    return !refuse(topic, dds::validate(m, limits_));
  }
  const dds::RejectionCounter& rejected() const noexcept { return rejected_; }

 private:
  struct LogGate {
    std::chrono::steady_clock::time_point last;
    uint64_t unlogged = 0;
  };
  dds::ValidationLimits limits_;
  dds::RejectionCounter rejected_;
  std::mutex log_mutex_;
  std::map<std::string, LogGate, std::less<>> log_gates_;
};

// The limits of a swarm of `robots` (ids 0 .. robots - 1) and the other node ids it accepts (a
// central's, say); dds::ValidationLimits' defaults otherwise.
dds::ValidationLimits swarm_limits(uint32_t robots, std::vector<uint32_t> extra_node_ids = {});

// How a service's domains are laid out.
enum class Domains {
  kSingle,       // one participant
  kRobot,        // the SLAM (radio) domain and, optionally, the robot's own; SIGUSR1/2 cut and restore the radio
  kWithSensors,  // the SLAM domain and, optionally, a domain for sensors and lock-step progress
};

class Service {
 public:
  // secondary: the robot's own domain (kRobot) or the sensors' (kWithSensors); nullopt for none.
  Service(Domains kind, const dds::ParticipantOptions& primary, const std::optional<dds::ParticipantOptions>& secondary,
          dds::ValidationLimits limits);
  // The domains the shared options name: the SLAM domain and, for kRobot, the robot's own (--local-domain);
  // for kWithSensors, sensors names the sensors' domain (nullopt: the SLAM domain). options() keeps them.
  Service(Domains kind, const ServiceOptions& options, dds::ValidationLimits limits,
          const std::optional<dds::ParticipantOptions>& sensors = std::nullopt);
  ~Service();
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  // The shared options the service started with (defaults when it was given domains instead).
  const ServiceOptions& options() const noexcept { return options_; }

  // The SLAM domain (the radio for a robot's services).
  const dds::Participant& radio() const noexcept;
  // The second domain, or the SLAM domain when there is none.
  const dds::Participant& secondary() const noexcept;
  bool split() const noexcept;
  // The radio switch of a robot's services (nullptr otherwise).
  const dds::RobotDomains* robot_domains() const noexcept { return robot_ ? &*robot_ : nullptr; }

  Boundary& boundary() noexcept { return boundary_; }
  const Boundary& boundary() const noexcept { return boundary_; }

  // wait() returns when this reader holds samples.
  void watch(dds_entity_t reader);
  // wait() returns when this guard is triggered (the node resets it), e.g. by a liveliness change.
  void watch(const dds::GuardCondition& guard);
  // Sleeps until a watched reader holds samples, shutdown is asked for, or timeout passes.
  // Returns false once shutdown is asked for.
  bool wait(std::chrono::nanoseconds timeout);
  static bool running() noexcept;

 private:
  ServiceOptions options_;
  std::optional<dds::RobotDomains> robot_;
  std::optional<dds::Participant> primary_, secondary_;
  Boundary boundary_;
  dds::GuardCondition stop_;
  dds::WaitSet waitset_;
  std::vector<std::unique_ptr<dds::ReadCondition>> conditions_;
};

}  // namespace cdc::runtime
