// A robot service's two DDS domains.
//
// radio(): the SLAM domain, shared with the other robots and the central node. It carries what
// crosses the radio: descriptors, loop closures, cloud requests and replies, separator poses, the
// central's poses and liveliness, keyframes for the central.
// local(): the robot's own domain, which never leaves the robot: keyframes with their clouds for
// the robot's own services, corrections for its front-end, its own descriptors and loop closures.
// Without a local domain both are one participant (a service on its own, the service tests).
//
// While a RobotDomains exists, SIGUSR1 makes the radio domain deaf and mute and SIGUSR2 makes it
// hear and speak again (see ShutdownSignal::on_user_signal): the emulated radio of cdc-launch's loopback
// mode, which cuts a robot off from every other node while its own services keep talking.
#pragma once

#include "cdc/dds/participant.hpp"

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>

namespace cdc::dds {

class RobotDomains {
 public:
  // local: the robot's own domain, or nullopt for one participant. notify (optional) is called
  // on the signal thread after each radio switch with the new state.
  RobotDomains(const ParticipantOptions& radio, const std::optional<ParticipantOptions>& local,
               std::function<void(bool in_range)> notify = {});
  ~RobotDomains();
  RobotDomains(const RobotDomains&) = delete;
  RobotDomains& operator=(const RobotDomains&) = delete;

  const Participant& radio() const noexcept { return radio_; }
  const Participant& local() const noexcept { return local_ ? *local_ : radio_; }
  // Whether the robot's own data travels on a domain of its own.
  bool split() const noexcept { return local_.has_value(); }
  bool in_range() const noexcept { return in_range_.load(); }
  uint64_t radio_cuts() const noexcept { return cuts_.load(); }

  // The switch the signals drive (public for tests and for in-process use).
  void set_in_range(bool in_range);

 private:
  Participant radio_;
  std::optional<Participant> local_;
  std::function<void(bool)> notify_;
  std::atomic<bool> in_range_{true};
  std::atomic<uint64_t> cuts_{0};
};

// Options of a robot's local domain from the command line: nullopt when local_domain < 0 or equal
// to the radio domain. An empty config means the radio domain's configuration.
std::optional<ParticipantOptions> local_domain_options(int local_domain, const std::string& config,
                                                       const ParticipantOptions& radio);

}  // namespace cdc::dds
