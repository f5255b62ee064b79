// Typed topics, writers, readers and taken samples over the Cyclone C API.
#pragma once

#include "cdc/dds/entity.hpp"
#include "cdc/dds/error.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/sample_buffers.hpp"
#include "cdc/dds/traffic.hpp"
#include "cdc/dds/types.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace cdc::dds {

namespace detail {
// A publisher (or subscriber) carrying the partitions `qos` names; an empty Entity when it names none.
Entity make_group(const Participant& participant, const Qos& qos, bool publisher);

// Deletes writers on threads of their own. Cyclone lets a deleted writer linger until its readers
// have acknowledged what it holds, up to WriterLingerDuration (1 s by default): a reader out of
// reach would stall the caller that long. The destructor waits for every deletion.
class WriterRetirement {
 public:
  WriterRetirement() = default;
  ~WriterRetirement();
  WriterRetirement(const WriterRetirement&) = delete;
  WriterRetirement& operator=(const WriterRetirement&) = delete;

  // Deletes the writer, then its publisher (empty when it has none).
  void retire(Entity publisher, Entity writer);
  // True once every writer retired so far is deleted, false if that takes longer than timeout.
  bool wait(std::chrono::milliseconds timeout) const;

 private:
  std::vector<std::thread> threads_;
  std::shared_ptr<std::atomic<int>> pending_ = std::make_shared<std::atomic<int>>(0);
};
}  // namespace detail

// Polls until pred() holds or timeout passes; returns pred()'s last value.
template <class Pred>
bool wait_until(Pred pred, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!pred()) {
    if (std::chrono::steady_clock::now() >= deadline) {
      return pred();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

template <class T>
class Topic {
 public:
  Topic(const Participant& participant, const std::string& name)
      : name_(name),
        domain_(participant.domain_id()),
        topic_(
            check(dds_create_topic(participant.handle(), TypeSupport<T>::descriptor(), name.c_str(), nullptr, nullptr),
                  "create topic '" + name + "'")) {}

  dds_entity_t handle() const noexcept { return topic_.handle(); }
  const std::string& name() const noexcept { return name_; }
  uint32_t domain() const noexcept { return domain_; }

 private:
  std::string name_;
  uint32_t domain_;
  Entity topic_;
};

template <class T>
class Writer {
 public:
  Writer(const Participant& participant, const Topic<T>& topic, const Qos& qos)
      : participant_(&participant),
        topic_handle_(topic.handle()),
        qos_(qos),
        topic_name_(topic.name()),
        counters_(&topic_counters(topic.domain(), topic.name())),
        publisher_(detail::make_group(participant, qos, true)),
        writer_(create()) {}

  // Drops every sample the writer still holds for readers that have not acknowledged it, so that
  // none is sent again when such a reader comes back in reach: the DDS writer is replaced by a
  // fresh one with the same QoS (matched anew by the readers; a volatile writer then delivers only
  // what is written from now on) and the old one deleted in the background (WriterRetirement).
  // For data that an application-level acknowledgement re-sends anyway, such as keyframes a
  // robot sent the central just before the radio link was cut.
  void discard_unacknowledged() {
    Entity fresh_publisher = detail::make_group(*participant_, qos_, true);
    Entity fresh_writer(create(fresh_publisher));
    retirement_.retire(std::exchange(publisher_, std::move(fresh_publisher)),
                       std::exchange(writer_, std::move(fresh_writer)));
  }

  // True once every writer replaced by discard_unacknowledged() is deleted (for tests).
  bool wait_discarded(std::chrono::milliseconds timeout) const { return retirement_.wait(timeout); }

  void write(const T& sample) {
    check(dds_write(writer_.handle(), &sample), "write on '" + topic_name_ + "'");
    samples_written_.fetch_add(1, std::memory_order_relaxed);
    counters_->samples_written.fetch_add(1, std::memory_order_relaxed);
    counters_->bytes_written.fetch_add(serialized_size(sample), std::memory_order_relaxed);
  }

  // Disposes the instance the sample's key fields name.
  void dispose(const T& sample) { check(dds_dispose(writer_.handle(), &sample), "dispose on '" + topic_name_ + "'"); }

  // Unregisters the instance the sample's key fields name: the writer and its readers stop keeping
  // it (samples not yet acknowledged are still delivered). For keyed streams whose every sample is a
  // new instance (keyframes, loop closures), which would otherwise stay registered for good.
  void unregister(const T& sample) {
    check(dds_unregister_instance(writer_.handle(), &sample), "unregister on '" + topic_name_ + "'");
  }

  // Tells readers this writer is alive (MANUAL_BY_TOPIC liveliness); writes do this too.
  void assert_liveliness() {
    check(dds_assert_liveliness(writer_.handle()), "assert liveliness on '" + topic_name_ + "'");
  }

  uint32_t matched_readers() const { return matched_status().current_count; }

  // Readers ever matched (a reader that went out of reach and came back counts again): a rise
  // means a reader may have missed samples written while it was away.
  uint32_t readers_ever_matched() const { return matched_status().total_count; }

  // Waits until at least n readers match. The first sample written before matching is lost
  // on a volatile topic: call this before the first write where that matters.
  bool wait_for_readers(uint32_t n, std::chrono::milliseconds timeout) const {
    return wait_until([&] { return matched_readers() >= n; }, timeout);
  }

  uint64_t samples_written() const noexcept { return samples_written_.load(); }
  dds_entity_t handle() const noexcept { return writer_.handle(); }
  const std::string& topic_name() const noexcept { return topic_name_; }

 private:
  dds_publication_matched_status_t matched_status() const {
    dds_publication_matched_status_t st{};
    check(dds_get_publication_matched_status(writer_.handle(), &st), "publication matched status");
    return st;
  }
  dds_entity_t create() const { return create(publisher_); }
  dds_entity_t create(const Entity& publisher) const {
    return check(
        dds_create_writer(publisher ? publisher.handle() : participant_->handle(), topic_handle_, qos_.get(), nullptr),
        "create writer on '" + topic_name_ + "'");
  }

  const Participant* participant_;  // outlives the writer, as every DDS entity's parent must
  dds_entity_t topic_handle_;
  Qos qos_;
  std::string topic_name_;
  TopicCounters* counters_;              // this process's counters of the topic (traffic.hpp)
  detail::WriterRetirement retirement_;  // declared before the entities: destroyed after them
  Entity publisher_;                     // own publisher when the QoS names partitions (deleted after the writer)
  Entity writer_;
  std::atomic<uint64_t> samples_written_{0};
};

namespace detail {
template <class T>
struct TopicMember {
  Topic<T> topic_;
};
}  // namespace detail

// A topic and its writer, for the usual case of a topic written by one writer: the writer, which also
// hands out the topic (for more writers of it, or for a liveliness monitor).
template <class T>
class TopicWriter : private detail::TopicMember<T>, public Writer<T> {
 public:
  TopicWriter(const Participant& participant, const std::string& topic, const Qos& qos)
      : detail::TopicMember<T>{Topic<T>(participant, topic)}, Writer<T>(participant, this->topic_, qos) {}

  const Topic<T>& topic() const noexcept { return this->topic_; }
};

// One writer of a topic per robot, each in that robot's partition (plus `also`, e.g. the writer's
// own), so that a sample meant for one robot crosses only the radio link to it (readers take it with
// partitions::own_reader). Made up front: a writer's first sample can be lost before it has matched.
// `skip` (this robot) gets none.
template <class T>
class PerRobotWriters {
 public:
  PerRobotWriters(const Participant& participant, const Topic<T>& topic, const Qos& qos, uint32_t robots,
                  std::optional<uint32_t> skip = std::nullopt, const std::vector<std::string>& also = {})
      : writers_(robots) {
    for (uint32_t r = 0; r < robots; ++r) {
      if (skip && *skip == r) continue;
      std::vector<std::string> names{partitions::robot(r)};
      names.insert(names.end(), also.begin(), also.end());
      writers_[r] = std::make_unique<Writer<T>>(participant, topic, Qos(qos).partitions(names));
    }
  }
  // The writer to robot r; nullptr for `skip` and for ids beyond the swarm.
  Writer<T>* to(uint32_t r) const noexcept { return r < writers_.size() ? writers_[r].get() : nullptr; }
  uint32_t size() const noexcept { return static_cast<uint32_t>(writers_.size()); }

 private:
  std::vector<std::unique_ptr<Writer<T>>> writers_;
};

template <class>
class Reader;

// Samples meant for a reader that it never got: lost on the way (a writer gave them up: DDS
// SAMPLE_LOST) or refused by the reader's resource limits (SAMPLE_REJECTED).
struct ReaderLosses {
  uint64_t lost = 0, rejected = 0;
};

// Samples taken by a reader, deserialised into the reader's reusable buffers: valid until this
// object is destroyed (the buffers go back to the reader then). The reader must outlive it.
template <class T>
class Samples {
 public:
  ~Samples() {
    if (home_ != nullptr && buffers_ && !*home_) {
      buffers_->recycle(count_);
      *home_ = std::move(buffers_);
    }
  }
  Samples(const Samples&) = delete;
  Samples& operator=(const Samples&) = delete;
  Samples(Samples&& other) noexcept
      : home_(std::exchange(other.home_, nullptr)),
        buffers_(std::move(other.buffers_)),
        infos_(std::move(other.infos_)),
        count_(std::exchange(other.count_, 0)) {}
  Samples& operator=(Samples&&) = delete;

  size_t size() const noexcept { return count_; }
  bool empty() const noexcept { return count_ == 0; }
  // False for samples that only carry an instance state change (dispose, no writers): their
  // data is unspecified, their info(i) holds what changed.
  bool valid(size_t i) const noexcept { return infos_[i].valid_data; }
  const T& operator[](size_t i) const noexcept { return *static_cast<const T*>((*buffers_)[i]); }
  const dds_sample_info_t& info(size_t i) const noexcept { return infos_[i]; }

  template <class F>
  void for_each_valid(F&& f) const {
    for (size_t i = 0; i < count_; ++i) {
      if (infos_[i].valid_data) {
        f((*this)[i], infos_[i]);
      }
    }
  }

 private:
  friend class Reader<T>;
  Samples(std::unique_ptr<detail::SampleBuffers>* home, std::unique_ptr<detail::SampleBuffers> buffers)
      : home_(home), buffers_(std::move(buffers)) {}
  std::unique_ptr<detail::SampleBuffers>* home_;  // the reader's spare slot
  std::unique_ptr<detail::SampleBuffers> buffers_;
  std::vector<dds_sample_info_t> infos_;
  size_t count_ = 0;
};

template <class T>
class Reader {
 public:
  Reader(const Participant& participant, const Topic<T>& topic, const Qos& qos)
      : topic_name_(topic.name()),
        counters_(&topic_counters(topic.domain(), topic.name())),
        subscriber_(detail::make_group(participant, qos, false)),
        reader_(check(dds_create_reader(subscriber_ ? subscriber_.handle() : participant.handle(), topic.handle(),
                                        qos.get(), nullptr),
                      "create reader on '" + topic.name() + "'")) {}

  // Takes up to max samples (removing them from the reader's cache). Each is deserialised once
  // and its serialised size counted as it came (traffic.hpp), without serialising it again.
  Samples<T> take(size_t max = 64) {
    auto buffers = spare_ ? std::move(spare_) : std::make_unique<detail::SampleBuffers>(TypeSupport<T>::descriptor());
    Samples<T> s(&spare_, std::move(buffers));
    uint64_t valid = 0, bytes = 0, failed = 0;
    s.count_ = s.buffers_->take(reader_.handle(), max, s.infos_, valid, bytes, failed, topic_name_.c_str());
    samples_taken_.fetch_add(s.count_, std::memory_order_relaxed);
    counters_->samples_taken.fetch_add(valid, std::memory_order_relaxed);
    counters_->bytes_taken.fetch_add(bytes, std::memory_order_relaxed);
    counters_->undecodable.fetch_add(failed, std::memory_order_relaxed);
    losses();
    return s;
  }

  // What this reader has lost or refused so far (noticed at every take, and by this call; counted in
  // the topic's traffic too).
  ReaderLosses losses() const {
    dds_sample_lost_status_t l{};
    check(dds_get_sample_lost_status(reader_.handle(), &l), "sample lost status on '" + topic_name_ + "'");
    dds_sample_rejected_status_t r{};
    check(dds_get_sample_rejected_status(reader_.handle(), &r), "sample rejected status on '" + topic_name_ + "'");
    // The change since the previous call (each call resets it): counted once however often asked.
    const auto lost = static_cast<uint64_t>(std::max(l.total_count_change, int32_t{0}));
    const auto rejected = static_cast<uint64_t>(std::max(r.total_count_change, int32_t{0}));
    counters_->samples_lost.fetch_add(lost, std::memory_order_relaxed);
    counters_->samples_rejected.fetch_add(rejected, std::memory_order_relaxed);
    return {lost_.fetch_add(lost) + lost, rejected_.fetch_add(rejected) + rejected};
  }

  uint32_t matched_writers() const {
    dds_subscription_matched_status_t st{};
    check(dds_get_subscription_matched_status(reader_.handle(), &st), "subscription matched status");
    return st.current_count;
  }

  bool wait_for_writers(uint32_t n, std::chrono::milliseconds timeout) const {
    return wait_until([&] { return matched_writers() >= n; }, timeout);
  }

  uint64_t samples_taken() const noexcept { return samples_taken_.load(); }
  dds_entity_t handle() const noexcept { return reader_.handle(); }
  const std::string& topic_name() const noexcept { return topic_name_; }

 private:
  std::string topic_name_;
  TopicCounters* counters_;  // this process's counters of the topic (traffic.hpp)
  Entity subscriber_;        // own subscriber when the QoS names partitions (deleted after the reader)
  Entity reader_;
  std::unique_ptr<detail::SampleBuffers> spare_;  // buffers not lent out, reused by the next take
  std::atomic<uint64_t> samples_taken_{0};
  mutable std::atomic<uint64_t> lost_{0}, rejected_{0};  // ReaderLosses so far
};

}  // namespace cdc::dds
