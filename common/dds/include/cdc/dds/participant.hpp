// A domain participant that never starts on an implicit (multicasting) configuration.
#pragma once

#include "cdc/dds/entity.hpp"

#include <cstdint>
#include <string>

namespace cdc::dds {

struct ParticipantOptions {
  // DDS domain id. Tests get theirs from CDC_DDS_DOMAIN (see domain_from_env).
  uint32_t domain_id = 0;
  // Cyclone configuration: "file://path.xml", an XML fragment, or a comma-separated list of both
  // (the CYCLONEDDS_URI syntax). Empty: use the CYCLONEDDS_URI environment variable.
  std::string config;
};

// Returns the configuration a participant would use (options.config, else CYCLONEDDS_URI).
// Throws DdsError when neither names one: cdc-slam refuses Cyclone's default configuration,
// which picks a real interface and multicasts discovery on it.
std::string resolve_config(const std::string& explicit_config);

// CDC_DDS_DOMAIN from the environment when set and valid (0..232), else fallback.
uint32_t domain_from_env(uint32_t fallback);

class Participant {
 public:
  explicit Participant(const ParticipantOptions& options);
  ~Participant();
  Participant(Participant&&) noexcept = default;
  Participant& operator=(Participant&&) noexcept = default;

  dds_entity_t handle() const noexcept { return participant_.handle(); }
  uint32_t domain_id() const noexcept { return domain_id_; }
  const std::string& config() const noexcept { return config_; }

  // Makes this participant's domain (in this process) ignore incoming packets (deaf) and drop
  // outgoing ones (mute), or hear and speak again: Cyclone's fault-injection switch, which the
  // loopback launcher uses as the emulated radio. Other domains of the process are unaffected.
  void set_deafmute(bool deaf, bool mute) const;

 private:
  Entity domain_;  // owned only when this participant created the domain
  Entity participant_;
  uint32_t domain_id_ = 0;
  std::string config_;
};

}  // namespace cdc::dds
