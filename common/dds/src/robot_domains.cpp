#include "cdc/dds/robot_domains.hpp"

#include "cdc/dds/shutdown.hpp"

#include <csignal>

namespace cdc::dds {

RobotDomains::RobotDomains(const ParticipantOptions& radio, const std::optional<ParticipantOptions>& local,
                           std::function<void(bool in_range)> notify)
    : radio_(radio), notify_(std::move(notify)) {
  if (local) local_.emplace(*local);
  ShutdownSignal::on_user_signal([this](int signal) { set_in_range(signal == SIGUSR2); });
}

RobotDomains::~RobotDomains() { ShutdownSignal::on_user_signal({}); }

void RobotDomains::set_in_range(bool in_range) {
  if (in_range_.exchange(in_range) == in_range) return;
  radio_.set_deafmute(!in_range, !in_range);
  if (!in_range) ++cuts_;
  if (notify_) notify_(in_range);
}

std::optional<ParticipantOptions> local_domain_options(int local_domain, const std::string& config,
                                                       const ParticipantOptions& radio) {
  if (local_domain < 0 || static_cast<uint32_t>(local_domain) == radio.domain_id) return std::nullopt;
  ParticipantOptions o;
  o.domain_id = static_cast<uint32_t>(local_domain);
  o.config = config.empty() ? radio.config : config;
  return o;
}

}  // namespace cdc::dds
