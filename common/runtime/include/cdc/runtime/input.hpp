// One input topic of a node: the reader, and the sequence every sample goes through on its way in.
// Not for this node (filter): skipped without a word. Invalid (dds::validate, then the node's own
// check): counted by topic and logged with the reason (Boundary). Otherwise handed to the handler,
// converted first when the node gives a conversion.
#pragma once

#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/runtime/service.hpp"

#include <functional>
#include <string>
#include <utility>

namespace cdc::runtime {

template <class Msg>
class Input {
 public:
  using Filter = std::function<bool(const Msg&)>;
  using Check = std::function<dds::Validation(const Msg&)>;
  using Handler = std::function<void(const Msg&, const dds_sample_info_t&)>;

  // A reader of `topic` on `participant`, watched by the service's waitset unless watch is false
  // (an input taken on every pass anyway).
  Input(Service& service, const dds::Participant& participant, const std::string& topic, const dds::Qos& qos,
        bool watch = true)
      : boundary_(&service.boundary()), topic_(participant, topic), reader_(participant, topic_, qos) {
    if (watch) service.watch(reader_.handle());
  }

  // Samples for which f is false are not for this node (another robot's, say).
  Input& filter(Filter f) {
    filter_ = std::move(f);
    return *this;
  }
  // A check of the node's own after dds::validate (order, state it knows).
  Input& check(Check c) {
    check_ = std::move(c);
    return *this;
  }
  Input& on(Handler h) {
    handler_ = std::move(h);
    return *this;
  }
  Input& on(std::function<void(const Msg&)> h) {
    handler_ = [h = std::move(h)](const Msg& m, const dds_sample_info_t&) { h(m); };
    return *this;
  }
  // convert(m) turns the message into what the node works with; handler takes that.
  template <class Convert, class Then>
  Input& on(Convert convert, Then then) {
    handler_ = [c = std::move(convert), t = std::move(then)](const Msg& m, const dds_sample_info_t&) { t(c(m)); };
    return *this;
  }

  // Takes up to max samples and passes each through the sequence; returns how many reached the handler.
  size_t poll(size_t max = 64) {
    size_t handled = 0;
    reader_.take(max).for_each_valid([&](const Msg& m, const dds_sample_info_t& info) {
      if (filter_ && !filter_(m)) return;
      dds::Validation v = dds::validate(m, boundary_->limits());
      if (v && check_) v = check_(m);
      if (boundary_->refuse(topic_.name(), v)) return;
      ++handled;
      if (handler_) handler_(m, info);
    });
    return handled;
  }

  dds::Reader<Msg>& reader() noexcept { return reader_; }
  const dds::Reader<Msg>& reader() const noexcept { return reader_; }
  const std::string& topic() const noexcept { return topic_.name(); }

 private:
  Boundary* boundary_;
  dds::Topic<Msg> topic_;
  dds::Reader<Msg> reader_;
  Filter filter_;
  Check check_;
  Handler handler_;
};

}  // namespace cdc::runtime
