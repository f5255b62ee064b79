#include "cdc/dds/pubsub.hpp"

namespace cdc::dds::detail {

WriterRetirement::~WriterRetirement() {
  for (std::thread& t : threads_) t.join();
}

void WriterRetirement::retire(Entity publisher, Entity writer) {
  // With every earlier deletion done their threads are joined here, so that a writer replaced at
  // every mode switch of a long run keeps no finished threads.
  if (pending_->load() == 0) {
    for (std::thread& t : threads_) t.join();
    threads_.clear();
  }
  pending_->fetch_add(1);
  threads_.emplace_back([publisher = std::move(publisher), writer = std::move(writer), pending = pending_]() mutable {
    writer.reset();  // returns once the writer stopped lingering
    publisher.reset();
    pending->fetch_sub(1);
  });
}

bool WriterRetirement::wait(std::chrono::milliseconds timeout) const {
  return wait_until([&] { return pending_->load() == 0; }, timeout);
}

}  // namespace cdc::dds::detail
