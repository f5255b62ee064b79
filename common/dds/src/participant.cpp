#include "cdc/dds/participant.hpp"

#include "cdc/dds/error.hpp"
#include "cdc/dds/traffic.hpp"

#include <cstdlib>
#include <string>

namespace cdc::dds {

std::string resolve_config(const std::string& explicit_config) {
  if (!explicit_config.empty()) {
    return explicit_config;
  }
  const char* env = std::getenv("CYCLONEDDS_URI");
  if (env != nullptr && env[0] != '\0') {
    return env;
  }
  throw DdsError(
      "no Cyclone DDS configuration: set CYCLONEDDS_URI (e.g. file://deploy/cyclonedds/loopback.xml) "
      "or pass --dds-config; cdc-slam refuses Cyclone's default, which multicasts on a real interface",
      DDS_RETCODE_PRECONDITION_NOT_MET);
}

uint32_t domain_from_env(uint32_t fallback) {
  const char* env = std::getenv("CDC_DDS_DOMAIN");
  if (env == nullptr || env[0] == '\0') {
    return fallback;
  }
  char* end = nullptr;
  const unsigned long v = std::strtoul(env, &end, 10);
  if (end == env || *end != '\0' || v > 232) {
    throw DdsError(std::string("CDC_DDS_DOMAIN='") + env + "' is not a domain id 0..232", DDS_RETCODE_BAD_PARAMETER);
  }
  return static_cast<uint32_t>(v);
}

Participant::Participant(const ParticipantOptions& options)
    : domain_id_(options.domain_id), config_(resolve_config(options.config)) {
  watch_undecodable_samples();
  // The configuration is always passed explicitly: a domain created here uses exactly it.
  const dds_entity_t domain = dds_create_domain(domain_id_, config_.c_str());
  if (domain > 0) {
    domain_ = Entity(domain);
  } else if (domain != DDS_RETCODE_PRECONDITION_NOT_MET) {  // not "domain exists already"
    check(domain, "create DDS domain " + std::to_string(domain_id_) + " with configuration '" + config_ + "'");
  }
  participant_ = Entity(check(dds_create_participant(domain_id_, nullptr, nullptr),
                              "create participant on domain " + std::to_string(domain_id_)));
}

void Participant::set_deafmute(bool deaf, bool mute) const {
  check(dds_domain_set_deafmute(participant_.handle(), deaf, mute, DDS_INFINITY),
        "set deaf/mute on domain " + std::to_string(domain_id_));
}

Participant::~Participant() {
  participant_.reset();
  domain_.reset();
}

}  // namespace cdc::dds
