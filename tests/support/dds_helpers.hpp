// DDS set-up shared by tests and test helper processes (header only; users link cdc_dds).
#pragma once

#include "cdc/dds/participant.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/waitset.hpp"

#include <chrono>
#include <cstdint>

namespace cdc::test {

// Participant options on `domain`.
inline dds::ParticipantOptions on_domain(uint32_t domain) {
  dds::ParticipantOptions o;
  o.domain_id = domain;
  return o;
}

// Participant options on the test's own domain (CDC_DDS_DOMAIN, else 0).
inline dds::ParticipantOptions test_domain() { return on_domain(dds::domain_from_env(0)); }

// A waitset that wakes (tag 0) when SIGINT/SIGTERM arrives, through a guard condition that the
// shutdown signal triggers; a helper process's loop waits on it between rounds.
class SignalWaitSet {
 public:
  explicit SignalWaitSet(const dds::Participant& participant) : stop_(participant), ws_(participant) {
    dds::ShutdownSignal::add_guard(&stop_);
    ws_.attach(stop_.handle(), 0);
  }
  ~SignalWaitSet() { dds::ShutdownSignal::remove_guard(&stop_); }
  SignalWaitSet(const SignalWaitSet&) = delete;
  SignalWaitSet& operator=(const SignalWaitSet&) = delete;

  dds::WaitSet& waitset() { return ws_; }
  void wait(std::chrono::milliseconds timeout) { ws_.wait(timeout); }

 private:
  dds::GuardCondition stop_;
  dds::WaitSet ws_;
};

}  // namespace cdc::test
