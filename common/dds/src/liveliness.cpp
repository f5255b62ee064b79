#include "cdc/dds/liveliness.hpp"

#include "cdc/base/names.hpp"
#include "cdc/dds/error.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/waitset.hpp"

#include <array>

namespace cdc::dds {
namespace {

constexpr std::array<base::Named<Liveliness>, 3> kLivelinessNames{
    {{Liveliness::kUnknown, "unknown"}, {Liveliness::kAlive, "alive"}, {Liveliness::kLost, "lost"}}};

void liveliness_changed_cb(dds_entity_t /*reader*/, const dds_liveliness_changed_status_t status, void* arg) {
  static_cast<LivelinessMonitor*>(arg)->on_liveliness_changed(static_cast<int32_t>(status.alive_count));
}

}  // namespace

const char* to_string(Liveliness state) noexcept { return base::name_of(kLivelinessNames, state, "unknown"); }

LivelinessMonitor::LivelinessMonitor(const Participant& participant, dds_entity_t topic, std::string name)
    : name_(std::move(name)) {
  dds_listener_t* listener = dds_create_listener(this);
  dds_lset_liveliness_changed(listener, liveliness_changed_cb);
  const Qos q = qos::monitored_reader();
  const dds_entity_t reader = dds_create_reader(participant.handle(), topic, q.get(), listener);
  dds_delete_listener(listener);
  reader_ = Entity(check(reader, "create liveliness monitor reader for '" + name_ + "'"));
}

LivelinessMonitor::~LivelinessMonitor() { reader_.reset(); }

void LivelinessMonitor::on_liveliness_changed(int32_t alive_count) {
  GuardCondition* notify = nullptr;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const Liveliness now = alive_count > 0 ? Liveliness::kAlive : Liveliness::kLost;
    if (now == state_) {
      return;  // another writer came or went; the topic's state is unchanged
    }
    LivelinessEvent ev;
    ev.state = now;
    ev.when = std::chrono::steady_clock::now();
    ev.wall_time_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
    ev.alive_writers = alive_count;
    state_ = now;
    last_ = ev;
    events_.push_back(ev);
    notify = notify_;
  }
  cv_.notify_all();
  if (notify != nullptr) {
    try {
      notify->trigger();
    } catch (...) {
      // never throw into Cyclone's thread
    }
  }
}

Liveliness LivelinessMonitor::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}

std::optional<LivelinessEvent> LivelinessMonitor::next_event(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!cv_.wait_for(lock, timeout, [&] { return !events_.empty(); })) {
    return std::nullopt;
  }
  LivelinessEvent ev = events_.front();
  events_.pop_front();
  return ev;
}

std::optional<LivelinessEvent> LivelinessMonitor::wait_for(Liveliness wanted, std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  const bool reached = cv_.wait_for(lock, timeout, [&] { return state_ == wanted; });
  if (!reached) {
    return std::nullopt;
  }
  events_.clear();
  return last_;
}

void LivelinessMonitor::set_notify(GuardCondition* guard) {
  std::lock_guard<std::mutex> lock(mutex_);
  notify_ = guard;
}

}  // namespace cdc::dds
