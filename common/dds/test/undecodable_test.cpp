// Samples Cyclone cannot deserialise never reach a reader: they are counted as undecodable on their topic
// from Cyclone's log (traffic.hpp). The writer here is another process with a forged type of the same name
// whose enum allows more values than cdc's, so the receiving side's check of the enum fails.
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/traffic.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>
#include <chrono>
#include <cstddef>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

namespace cdc::dds {
namespace {

using namespace std::chrono_literals;

TEST(Undecodable, CyclonesWarningIsCountedOnItsTopic) {
  const uint64_t before = topic_counters(7, "cdc/test/parse").undecodable.load();
  EXPECT_TRUE(count_undecodable_message(
      7,
      "data(application, vendor 1.16): 1101a2b3:4c5d:6e7f:103 #12: deserialization cdc/test/parse/cdc::msg::ModeState "
      "failed (invalid enum value)\n"));
  EXPECT_EQ(topic_counters(7, "cdc/test/parse").undecodable.load(), before + 1);
  EXPECT_FALSE(count_undecodable_message(7, "data(application, vendor 1.16): write without proper payload\n"));
  EXPECT_FALSE(count_undecodable_message(7, "some other warning about deserialization\n"));
  EXPECT_EQ(topic_counters(7, "cdc/test/parse").undecodable.load(), before + 1);
}

// ModeState's descriptor with the enum `mode` widened to 8 values and no XTypes information, so that it
// matches cdc's type by name and its writer accepts mode = 5.
struct ForgedModeState {
  std::vector<uint32_t> ops;
  dds_topic_descriptor_t desc;

  static std::vector<uint32_t> widened_ops() {
    const dds_topic_descriptor_t* d = TypeSupport<cdc_msg_ModeState>::descriptor();
    // ModeState holds only primitives (ADR, offset) and enums (ADR, offset, max), then RTS and its key list.
    size_t n = 0;
    while (d->m_ops[n] != DDS_OP_RTS) n += DDS_OP_TYPE(d->m_ops[n]) == DDS_OP_VAL_ENU ? 3 : 2;
    ++n;
    for (uint32_t k = 0; k < d->m_nkeys; ++k) n += 1 + (d->m_ops[n] & 0xffffu);  // KOF | count, then the offsets
    std::vector<uint32_t> ops(d->m_ops, d->m_ops + n);
    for (size_t i = 0; i + 2 < ops.size(); ++i) {
      if (DDS_OP(ops[i]) == DDS_OP_ADR && DDS_OP_TYPE(ops[i]) == DDS_OP_VAL_ENU &&
          ops[i + 1] == offsetof(cdc_msg_ModeState, mode)) {
        ops[i + 2] = 7;
        return ops;
      }
    }
    ADD_FAILURE() << "ModeState's ops have no enum at mode";
    return ops;
  }

  ForgedModeState() : ops(widened_ops()), desc(forged(ops)) {}

  static dds_topic_descriptor_t forged(const std::vector<uint32_t>& ops) {
    const dds_topic_descriptor_t* d = TypeSupport<cdc_msg_ModeState>::descriptor();
    return dds_topic_descriptor_t{d->m_size,    d->m_align,    d->m_flagset & ~DDS_TOPIC_XTYPES_METADATA,
                                  d->m_nkeys,   d->m_typename, d->m_keys,
                                  d->m_nops,    ops.data(),    d->m_meta,
                                  {nullptr, 0}, {nullptr, 0},  d->restrict_data_representation};
  }
};

// The child: writes out-of-range samples for a while, then leaves.
[[noreturn]] void write_forged(const std::string& topic_name) {
  ParticipantOptions po;
  po.domain_id = domain_from_env(0);
  Participant p(po);
  ForgedModeState forged;
  const dds_entity_t topic = dds_create_topic(p.handle(), &forged.desc, topic_name.c_str(), nullptr, nullptr);
  const dds_entity_t writer = dds_create_writer(p.handle(), topic, nullptr, nullptr);
  if (topic < 0 || writer < 0) ::_exit(3);
  cdc_msg_ModeState s{};
  s.robot_id = 1;
  const uint32_t out_of_range = 5;  // the C enum holds it; C++ may not name it
  static_assert(sizeof s.mode == sizeof out_of_range);
  std::memcpy(&s.mode, &out_of_range, sizeof out_of_range);
  for (int i = 0; i < 40; ++i) {
    s.stamp_ns = i;
    dds_write(writer, &s);
    std::this_thread::sleep_for(100ms);
  }
  ::_exit(0);
}

TEST(Undecodable, SamplesCycloneDropsAreCountedOnTheReadersTopic) {
  const std::string name = "cdc/test/forged_" + std::to_string(::getpid());
  const pid_t child = ::fork();  // before this process starts any DDS thread
  ASSERT_GE(child, 0);
  if (child == 0) write_forged(name);
  ParticipantOptions po;
  po.domain_id = domain_from_env(0);
  Participant p(po);
  Topic<cdc_msg_ModeState> topic(p, name);
  Reader<cdc_msg_ModeState> reader(p, topic, Qos().reliable());
  uint64_t undecodable = 0;
  size_t taken = 0;
  for (int i = 0; i < 100 && undecodable == 0; ++i) {
    std::this_thread::sleep_for(50ms);
    taken += reader.take().size();
    undecodable = topic_counters(po.domain_id, name).undecodable.load();
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the forging writer failed";
  EXPECT_GE(undecodable, 1u) << "no undeserialisable sample was counted";
  EXPECT_EQ(taken, 0u) << "a sample with an enum out of range reached the reader";
}

}  // namespace
}  // namespace cdc::dds
