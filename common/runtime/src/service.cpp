#include "cdc/runtime/service.hpp"

#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/logging.hpp"

#include <spdlog/spdlog.h>

#include <cctype>
#include <utility>

namespace cdc::runtime {

namespace {

// "topic|reason" with every run of digits in the reason folded to one '#': refusals that differ only by
// ids, counts or positions share a log gate.
std::string gate_key(std::string_view topic, const std::string& reason) {
  std::string key(topic);
  key += '|';
  for (size_t i = 0; i < reason.size(); ++i) {
    if (std::isdigit(static_cast<unsigned char>(reason[i])) == 0) {
      key += reason[i];
    } else if (i == 0 || std::isdigit(static_cast<unsigned char>(reason[i - 1])) == 0) {
      key += '#';
    }
  }
  return key;
}

}  // namespace

bool Boundary::refuse(std::string_view topic, const dds::Validation& v, bool* logged) {
  if (!rejected_.record(topic, v)) return false;
  const auto now = std::chrono::steady_clock::now();
  const std::lock_guard<std::mutex> lock(log_mutex_);
  std::string key = gate_key(topic, v.reason());
  if (log_gates_.size() >= kMaxLogGates && !log_gates_.count(key)) key = std::string(topic) + '|';
  auto gate = log_gates_.find(key);
  const bool first = gate == log_gates_.end();
  if (first) gate = log_gates_.emplace(std::move(key), LogGate{now, 0}).first;
  const bool log = first || now - gate->second.last >= kLogPeriod;
  if (logged != nullptr) *logged = log;
  if (!log) {
    ++gate->second.unlogged;
    return true;
  }
  if (gate->second.unlogged > 0) {
    spdlog::warn("rejected {}: {} (and {} more not logged in the last {:.1f} s)", topic, v.reason(),
                 gate->second.unlogged, std::chrono::duration<double>(now - gate->second.last).count());
  } else {
    spdlog::warn("rejected {}: {}", topic, v.reason());
  }
  gate->second = {now, 0};
  return true;
}

dds::ValidationLimits swarm_limits(uint32_t robots, std::vector<uint32_t> extra_node_ids) {
  dds::ValidationLimits l;
  l.robot_count = robots;
  l.extra_node_ids = std::move(extra_node_ids);
  return l;
}

Service::Service(Domains kind, const dds::ParticipantOptions& primary,
                 const std::optional<dds::ParticipantOptions>& secondary, dds::ValidationLimits limits)
    : boundary_(std::move(limits)) {
  if (kind == Domains::kRobot) {
    robot_.emplace(primary, secondary, log_radio_switch);
  } else {
    primary_.emplace(primary);
    if (kind == Domains::kWithSensors && secondary && secondary->domain_id != primary.domain_id) {
      secondary_.emplace(*secondary);
    }
  }
  waitset_.attach(stop_.handle(), 0);
  dds::ShutdownSignal::add_guard(&stop_);
}

Service::Service(Domains kind, const ServiceOptions& options, dds::ValidationLimits limits,
                 const std::optional<dds::ParticipantOptions>& sensors)
    : Service(kind, options.radio(), kind == Domains::kRobot ? options.local() : sensors, std::move(limits)) {
  options_ = options;
}

Service::~Service() { dds::ShutdownSignal::remove_guard(&stop_); }

const dds::Participant& Service::radio() const noexcept { return robot_ ? robot_->radio() : *primary_; }

const dds::Participant& Service::secondary() const noexcept {
  if (robot_) return robot_->local();
  return secondary_ ? *secondary_ : *primary_;
}

bool Service::split() const noexcept { return robot_ ? robot_->split() : secondary_.has_value(); }

void Service::watch(dds_entity_t reader) {
  conditions_.push_back(std::make_unique<dds::ReadCondition>(reader));
  waitset_.attach(conditions_.back()->handle(), static_cast<intptr_t>(conditions_.size()));
}

void Service::watch(const dds::GuardCondition& guard) {
  waitset_.attach(guard.handle(), -1);  // wait() reads no tags
}

bool Service::wait(std::chrono::nanoseconds timeout) {
  if (!running()) return false;
  waitset_.wait(timeout);
  return running();
}

bool Service::running() noexcept { return !dds::ShutdownSignal::requested(); }

}  // namespace cdc::runtime
