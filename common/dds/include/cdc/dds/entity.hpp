// Move-only owner of a Cyclone entity handle: deletes it (and its children) on destruction.
#pragma once

#include <dds/dds.h>

#include <utility>

namespace cdc::dds {

class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  ~Entity() { reset(); }
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;
  Entity(Entity&& other) noexcept : handle_(std::exchange(other.handle_, 0)) {}
  Entity& operator=(Entity&& other) noexcept {
    if (this != &other) {
      reset();
      handle_ = std::exchange(other.handle_, 0);
    }
    return *this;
  }

  dds_entity_t handle() const noexcept { return handle_; }
  explicit operator bool() const noexcept { return handle_ > 0; }

  void reset() noexcept {
    if (handle_ > 0) {
      dds_delete(handle_);
    }
    handle_ = 0;
  }

 private:
  dds_entity_t handle_ = 0;
};

}  // namespace cdc::dds
