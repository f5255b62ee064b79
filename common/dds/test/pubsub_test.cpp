// Participants, typed pub/sub, waitsets and conversions over Cyclone on the loopback configuration.
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/cloud_convert.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/error.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/dds/waitset.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <unistd.h>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <thread>

namespace cdc::dds {
namespace {

using namespace std::chrono_literals;

ParticipantOptions test_options() {
  ParticipantOptions o;
  o.domain_id = domain_from_env(0);
  return o;
}

std::string unique_topic(const std::string& base) { return "cdc/test/" + base + "_" + std::to_string(::getpid()); }

// A participant with one writer and one reader of a fresh topic, both with the same QoS.
template <class T>
struct WriterAndReader {
  WriterAndReader(const std::string& topic_base, const Qos& qos)
      : topic(participant, unique_topic(topic_base)),
        writer(participant, topic, qos),
        reader(participant, topic, qos) {}

  Participant participant{test_options()};
  Topic<T> topic;
  Writer<T> writer;
  Reader<T> reader;
};

TEST(Participant, RefusesToStartWithoutExplicitConfiguration) {
  const char* saved = std::getenv("CYCLONEDDS_URI");
  ASSERT_NE(saved, nullptr) << "ctest must run DDS tests with CYCLONEDDS_URI set to the loopback configuration";
  const std::string keep = saved;
  ::unsetenv("CYCLONEDDS_URI");
  try {
    Participant p(test_options());
    ::setenv("CYCLONEDDS_URI", keep.c_str(), 1);
    FAIL() << "a participant started without a configuration";
  } catch (const DdsError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("no Cyclone DDS configuration"));
  }
  ::setenv("CYCLONEDDS_URI", "", 1);
  EXPECT_THROW(Participant p(test_options()), DdsError);
  ::setenv("CYCLONEDDS_URI", keep.c_str(), 1);
}

TEST(Participant, TestsRunOnTheLoopbackConfiguration) {
  const std::string uri = std::getenv("CYCLONEDDS_URI");
  EXPECT_THAT(uri, ::testing::EndsWith("deploy/cyclonedds/loopback.xml"));
  Participant p(test_options());
  EXPECT_GT(p.handle(), 0);
  EXPECT_EQ(p.config(), uri);
}

TEST(Participant, RejectsABadDomainEnvironment) {
  ::setenv("CDC_DDS_DOMAIN", "999", 1);
  EXPECT_THROW(domain_from_env(0), DdsError);
  ::unsetenv("CDC_DDS_DOMAIN");
  EXPECT_EQ(domain_from_env(5), 5u);
}

struct KeyframeSample {
  explicit KeyframeSample(size_t n) {
    cloud.resize(n);
    for (size_t i = 0; i < n; ++i) {
      cloud[i].x = static_cast<float>(i);
      cloud[i].y = static_cast<float>(i) * 0.5f;
      cloud[i].z = -1.0f;
      cloud[i].intensity = 0.25f;
    }
    from_pcl(cloud, storage);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(1, 2, 3);
    T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    msg.robot_id = 2;
    msg.keyframe_id = 5;
    msg.incarnation = 77;
    msg.stamp_ns = 123;
    msg.T_odom_keyframe = to_msg(T);
    msg.T_prev_keyframe = to_msg(Eigen::Isometry3d::Identity());
    information_to_msg(Matrix6d::Identity() * 10.0, msg.information);
    borrow(msg.cloud, storage);
    msg.point_count = static_cast<uint32_t>(n);
  }
  pcl::PointCloud<pcl::PointXYZI> cloud;
  std::vector<cdc_msg_PointXYZI> storage;
  cdc_msg_Keyframe msg{};
};

TEST(PubSub, KeyframeWithCloudRoundTripsThroughAWaitset) {
  WriterAndReader<cdc_msg_Keyframe> wr("keyframe", qos::keyed_state());
  auto& [p, topic, writer, reader] = wr;
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));

  ReadCondition rc(reader.handle());
  WaitSet ws(p);
  ws.attach(rc.handle(), 1);

  KeyframeSample sample(1000);
  writer.write(sample.msg);
  EXPECT_EQ(writer.samples_written(), 1u);

  const auto tags = ws.wait(5s);
  ASSERT_EQ(tags.size(), 1u);
  EXPECT_EQ(tags[0], 1);
  auto taken = reader.take();
  ASSERT_EQ(taken.size(), 1u);
  ASSERT_TRUE(taken.valid(0));
  const cdc_msg_Keyframe& got = taken[0];
  EXPECT_TRUE(validate(got, ValidationLimits{}));
  EXPECT_EQ(got.robot_id, 2u);
  EXPECT_EQ(got.keyframe_id, 5u);
  EXPECT_EQ(got.incarnation, 77u);
  EXPECT_LT((to_eigen(got.T_odom_keyframe).matrix() - to_eigen(sample.msg.T_odom_keyframe).matrix()).norm(), 1e-12);
  EXPECT_DOUBLE_EQ(information_to_eigen(got.information)(3, 3), 10.0);
  pcl::PointCloud<pcl::PointXYZI> back;
  to_pcl(got.cloud, back);
  ASSERT_EQ(back.size(), 1000u);
  EXPECT_FLOAT_EQ(back[999].x, 999.0f);
  EXPECT_FLOAT_EQ(back[999].y, 499.5f);
  EXPECT_FLOAT_EQ(back[10].intensity, 0.25f);
}

TEST(PubSub, PerTopicTrafficCountsSerialisedBytesWrittenAndTaken) {
  WriterAndReader<cdc_msg_Keyframe> wr("traffic", qos::event_stream());
  auto& [p, topic, writer, reader] = wr;
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));
  KeyframeSample small(1000), large(2000);
  writer.write(small.msg);
  const TopicTotals after_one = topic_traffic().at({topic.domain(), topic.name()});
  writer.write(large.msg);
  size_t taken = 0;
  ASSERT_TRUE(wait_until([&] { return (taken += reader.take().size()) == 2; }, 5000ms));
  const TopicTotals t = topic_traffic().at({topic.domain(), topic.name()});
  EXPECT_EQ(t.samples_written, 2u);
  EXPECT_EQ(t.samples_taken, 2u);
  // 1000 more points of four floats each; what was taken is what was written.
  EXPECT_EQ(t.bytes_written - 2 * after_one.bytes_written, 1000u * 16u);
  EXPECT_GT(after_one.bytes_written, 1000u * 16u);
  EXPECT_EQ(t.bytes_taken, t.bytes_written);
}

// Samples a reader's resource limits refuse never reach take(): the reader counts them, and so does
// the topic's traffic.
TEST(PubSub, SamplesTheReaderRefusesAreCounted) {
  Qos qos;
  qos.best_effort().keep_all();
  Qos limited = qos;
  dds_qset_resource_limits(limited.get(), 4, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  Participant participant{test_options()};
  Topic<cdc_msg_Keyframe> topic(participant, unique_topic("refused"));
  Writer<cdc_msg_Keyframe> writer(participant, topic, qos);
  Reader<cdc_msg_Keyframe> reader(participant, topic, limited);
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));
  KeyframeSample sample(10);
  for (uint32_t id = 0; id < 10; ++id) {
    sample.msg.keyframe_id = id;
    writer.write(sample.msg);
  }
  ASSERT_TRUE(wait_until([&] { return reader.losses().rejected == 6; }, 5000ms))
      << "rejected " << reader.losses().rejected;
  EXPECT_EQ(reader.take(64).size(), 4u);
  EXPECT_EQ(reader.losses().rejected, 6u);
  EXPECT_EQ(reader.losses().lost, 0u);
  EXPECT_EQ(topic_traffic().at({topic.domain(), topic.name()}).samples_rejected, 6u);
}

TEST(PubSub, MalformedSampleIsRejectedAtTheReaderBoundary) {
  WriterAndReader<cdc_msg_Keyframe> wr("bad_keyframe", qos::event_stream());
  auto& [p, topic, writer, reader] = wr;
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));

  KeyframeSample good(10);
  KeyframeSample bad(10);
  bad.msg.keyframe_id = 6;
  bad.msg.T_odom_keyframe.orientation.w = std::numeric_limits<double>::quiet_NaN();
  KeyframeSample lying(10);
  lying.msg.keyframe_id = 7;
  lying.msg.point_count = 11;
  writer.write(good.msg);
  writer.write(bad.msg);
  writer.write(lying.msg);

  RejectionCounter rejected;
  std::vector<uint32_t> accepted;
  ASSERT_TRUE(wait_until(
      [&] {
        reader.take().for_each_valid([&](const cdc_msg_Keyframe& k, const dds_sample_info_t&) {
          const Validation v = validate(k, ValidationLimits{});
          if (!rejected.record(topic.name(), v)) {
            accepted.push_back(k.keyframe_id);
          }
        });
        return accepted.size() + rejected.total() == 3;
      },
      5000ms));
  EXPECT_EQ(accepted, std::vector<uint32_t>{5});
  EXPECT_EQ(rejected.count(topic.name()), 2u);
  EXPECT_THAT(rejected.last_reason(), ::testing::HasSubstr("length mismatch"));
}

// The transition counts of the first mode samples the reader takes within 5 s (none: empty).
std::vector<uint32_t> first_transition_counts(Reader<cdc_msg_ModeState>& reader) {
  std::vector<uint32_t> seen;
  wait_until(
      [&] {
        reader.take().for_each_valid(
            [&](const cdc_msg_ModeState& s, const dds_sample_info_t&) { seen.push_back(s.transition_count); });
        return !seen.empty();
      },
      5000ms);
  return seen;
}

TEST(PubSub, TransientLocalStateReachesALateJoiner) {
  Participant p(test_options());
  Topic<cdc_msg_ModeState> topic(p, unique_topic("mode"));
  Writer<cdc_msg_ModeState> writer(p, topic, qos::keyed_state());
  cdc_msg_ModeState m{};
  m.robot_id = 1;
  m.mode = cdc_msg_MODE_DISTRIBUTED;
  m.reason = cdc_msg_REASON_OUT_OF_RANGE;
  m.transition_count = 3;
  writer.write(m);
  m.transition_count = 4;
  writer.write(m);  // keep-last 1 per instance: only this one survives

  Reader<cdc_msg_ModeState> late(p, topic, qos::keyed_state());
  EXPECT_EQ(first_transition_counts(late), std::vector<uint32_t>{4});
}

// A reader reuses one set of sample buffers, grown by its largest take so far: a small take after
// a large one must still get every sample once, in order, and stay within the wrapper's arrays (the
// asan preset checks the latter).
TEST(PubSub, TakesOfDifferentSizesOnOneReaderGetEverySampleOnce) {
  WriterAndReader<cdc_msg_ModeState> wr("take_sizes", qos::event_stream(256));
  auto& [p, topic, writer, reader] = wr;
  ASSERT_TRUE(writer.wait_for_readers(1, 5000ms));
  cdc_msg_ModeState m{};
  m.robot_id = 1;
  m.mode = cdc_msg_MODE_CENTRALIZED;
  m.reason = cdc_msg_REASON_STARTUP;
  std::vector<uint32_t> seen;
  auto collect = [&](size_t max, size_t want) {
    return wait_until(
        [&] {
          const Samples<cdc_msg_ModeState> s = reader.take(max);
          EXPECT_LE(s.size(), max);
          s.for_each_valid(
              [&](const cdc_msg_ModeState& x, const dds_sample_info_t&) { seen.push_back(x.transition_count); });
          return seen.size() >= want;
        },
        5000ms);
  };
  for (uint32_t i = 0; i < 40; ++i) {
    m.transition_count = i;
    writer.write(m);
  }
  ASSERT_TRUE(collect(64, 40));
  for (uint32_t i = 40; i < 80; ++i) {
    m.transition_count = i;
    writer.write(m);
  }
  ASSERT_TRUE(collect(3, 80));  // many small takes on the large loan
  std::vector<uint32_t> want(80);
  for (uint32_t i = 0; i < 80; ++i) want[i] = i;
  EXPECT_EQ(seen, want);
}

// Samples stay valid while held: a second take while the first is still out fills other buffers,
// and the buffers handed back are reused, sequences and all, by the next take.
TEST(PubSub, SamplesStillHeldKeepTheirDataWhenTheReaderTakesAgain) {
  WriterAndReader<cdc_msg_Keyframe> wr("held", qos::event_stream(16));
  auto& [p, topic, writer, reader] = wr;
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));
  KeyframeSample big(3000), small(10), medium(200);
  big.msg.keyframe_id = 1;
  small.msg.keyframe_id = 2;
  medium.msg.keyframe_id = 3;
  writer.write(big.msg);
  writer.write(small.msg);
  std::vector<Samples<cdc_msg_Keyframe>> held;
  ASSERT_TRUE(wait_until(
      [&] {
        Samples<cdc_msg_Keyframe> s = reader.take(1);
        if (!s.empty()) held.push_back(std::move(s));
        return held.size() == 2;
      },
      5000ms));
  ASSERT_TRUE(held[0].valid(0) && held[1].valid(0));
  EXPECT_EQ(held[0][0].keyframe_id, 1u);
  EXPECT_EQ(held[0][0].cloud._length, 3000u);
  EXPECT_EQ(held[1][0].keyframe_id, 2u);
  EXPECT_EQ(held[1][0].cloud._length, 10u);
  held.clear();  // both sets go back; one is kept for reuse
  writer.write(medium.msg);
  std::vector<uint32_t> ids, lengths;
  std::vector<float> last_x;
  ASSERT_TRUE(wait_until(
      [&] {
        reader.take().for_each_valid([&](const cdc_msg_Keyframe& k, const dds_sample_info_t&) {
          ids.push_back(k.keyframe_id);
          lengths.push_back(k.cloud._length);
          last_x.push_back(k.cloud._buffer[k.cloud._length - 1].x);
        });
        return !ids.empty();
      },
      5000ms));
  EXPECT_EQ(ids, std::vector<uint32_t>{3});
  EXPECT_EQ(lengths, std::vector<uint32_t>{200});
  EXPECT_EQ(last_x, std::vector<float>{199.0f});
  EXPECT_EQ(topic_traffic().at({topic.domain(), topic.name()}).samples_taken, 3u);
}

// A backlog taken at once: the samples beyond the first few give their clouds back when the set is
// returned (a backlog must not pin its memory), and the recycled buffers read the next backlog right.
TEST(PubSub, RecycledBuffersReadTheNextBacklogExactly) {
  WriterAndReader<cdc_msg_Keyframe> wr("backlog", qos::event_stream(64));
  auto& [p, topic, writer, reader] = wr;
  ASSERT_TRUE(writer.wait_for_readers(1, 5s));
  for (const size_t base : {100u, 7u}) {
    std::vector<uint32_t> want, got;
    for (uint32_t i = 0; i < 8; ++i) {
      KeyframeSample k(base * (i + 1) + i);
      k.msg.keyframe_id = i;
      writer.write(k.msg);
      want.push_back(static_cast<uint32_t>(base * (i + 1) + i));
    }
    ASSERT_TRUE(wait_until(
        [&] {
          reader.take().for_each_valid([&](const cdc_msg_Keyframe& m, const dds_sample_info_t&) {
            EXPECT_EQ(m.cloud._buffer[m.cloud._length - 1].x, static_cast<float>(m.cloud._length - 1));
            got.push_back(m.cloud._length);
          });
          return got.size() >= want.size();
        },
        5000ms));
    EXPECT_EQ(got, want) << "clouds of " << base << " points and up";
  }
}

// A robot's partition keeps its data from other robots' readers; the central's wildcard reader and
// tools on the default partition still see it.
TEST(PubSub, PartitionsKeepRobotDataFromOtherRobots) {
  Participant p(test_options());
  Topic<cdc_msg_ModeState> topic(p, unique_topic("partitioned"));
  Writer<cdc_msg_ModeState> robot1(p, topic, qos::keyed_state().partitions({partitions::robot(1)}));
  Reader<cdc_msg_ModeState> own(p, topic, qos::keyed_state().partitions(partitions::own_reader(1)));
  Reader<cdc_msg_ModeState> other(p, topic, qos::keyed_state().partitions(partitions::own_reader(2)));
  Reader<cdc_msg_ModeState> central(p, topic, qos::keyed_state().partitions(partitions::all_robots_reader()));
  Reader<cdc_msg_ModeState> plain(p, topic, qos::keyed_state());
  EXPECT_EQ(qos::keyed_state().partitions({partitions::robot(1)}).partitions(), std::vector<std::string>{"robot/1"});
  ASSERT_TRUE(robot1.wait_for_readers(2, 5000ms));
  cdc_msg_ModeState m{};
  m.robot_id = 1;
  m.mode = cdc_msg_MODE_CENTRALIZED;
  m.reason = cdc_msg_REASON_STARTUP;
  robot1.write(m);
  size_t got_own = 0, got_central = 0;
  ASSERT_TRUE(wait_until(
      [&] {
        got_own += own.take().size();
        got_central += central.take().size();
        return got_own > 0 && got_central > 0;
      },
      5000ms));
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(robot1.matched_readers(), 2u);  // own and central only
  EXPECT_EQ(other.take().size(), 0u);
  EXPECT_EQ(plain.take().size(), 0u);
  // A tool writing on the default partition reaches a robot's own reader.
  Writer<cdc_msg_ModeState> tool(p, topic, qos::keyed_state());
  ASSERT_TRUE(tool.wait_for_readers(4, 5000ms));
  m.robot_id = 2;
  tool.write(m);
  size_t got_other = 0;
  ASSERT_TRUE(wait_until([&] { return (got_other += other.take().size()) > 0; }, 5000ms));
}

// One writer per robot: a sample for robot 1 reaches robot 1's reader only, and a reader that
// comes back (a new match) shows in readers_ever_matched.
TEST(PubSub, PerRobotWritersReachOnlyTheirRobot) {
  Participant p(test_options());
  Topic<cdc_msg_ModeState> topic(p, unique_topic("per_robot"));
  PerRobotWriters<cdc_msg_ModeState> to(p, topic, qos::keyed_state(), 3, 0u);
  EXPECT_EQ(to.size(), 3u);
  EXPECT_EQ(to.to(0), nullptr);  // the skipped robot (the writer's own)
  EXPECT_EQ(to.to(3), nullptr);  // beyond the swarm
  ASSERT_NE(to.to(1), nullptr);
  ASSERT_NE(to.to(2), nullptr);
  auto r1 =
      std::make_unique<Reader<cdc_msg_ModeState>>(p, topic, qos::keyed_state().partitions(partitions::own_reader(1)));
  Reader<cdc_msg_ModeState> r2(p, topic, qos::keyed_state().partitions(partitions::own_reader(2)));
  ASSERT_TRUE(to.to(1)->wait_for_readers(1, 5000ms));
  ASSERT_TRUE(to.to(2)->wait_for_readers(1, 5000ms));
  EXPECT_EQ(to.to(1)->readers_ever_matched(), 1u);
  cdc_msg_ModeState m{};
  m.robot_id = 0;
  m.mode = cdc_msg_MODE_DISTRIBUTED;
  m.reason = cdc_msg_REASON_STARTUP;
  to.to(1)->write(m);
  size_t got1 = 0;
  ASSERT_TRUE(wait_until([&] { return (got1 += r1->take().size()) > 0; }, 5000ms));
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(r2.take().size(), 0u) << "robot 2 got a sample meant for robot 1";

  r1.reset();  // robot 1's reader goes and comes back: a second match
  r1 = std::make_unique<Reader<cdc_msg_ModeState>>(p, topic, qos::keyed_state().partitions(partitions::own_reader(1)));
  ASSERT_TRUE(wait_until([&] { return to.to(1)->readers_ever_matched() == 2u; }, 5000ms));
  EXPECT_EQ(to.to(1)->matched_readers(), 1u);
  EXPECT_EQ(to.to(2)->readers_ever_matched(), 1u);
}

TEST(WaitSet, GuardConditionWakesTheWaiter) {
  Participant p(test_options());
  GuardCondition guard(p);
  WaitSet ws(p);
  ws.attach(guard.handle(), 9);
  EXPECT_TRUE(ws.wait(20ms).empty());
  std::thread t([&] {
    std::this_thread::sleep_for(50ms);
    guard.trigger();
  });
  const auto start = std::chrono::steady_clock::now();
  const auto tags = ws.wait(5s);
  t.join();
  ASSERT_EQ(tags.size(), 1u);
  EXPECT_EQ(tags[0], 9);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 4s);
  EXPECT_TRUE(guard.triggered());
  guard.reset();
  EXPECT_FALSE(guard.triggered());
}

// A TopicWriter is a writer of the topic it names; its topic() serves further readers and writers.
TEST(PubSub, TopicWriterWritesTheTopicItHandsOut) {
  Participant p(test_options());
  TopicWriter<cdc_msg_ModeState> writer(p, unique_topic("mode_writer"), qos::keyed_state());
  EXPECT_EQ(writer.topic().name(), unique_topic("mode_writer"));
  EXPECT_EQ(writer.topic_name(), writer.topic().name());
  Reader<cdc_msg_ModeState> reader(p, writer.topic(), qos::keyed_state());
  ASSERT_TRUE(writer.wait_for_readers(1, 5000ms));
  cdc_msg_ModeState m{};
  m.robot_id = 2;
  m.transition_count = 7;
  writer.write(m);
  EXPECT_EQ(first_transition_counts(reader), std::vector<uint32_t>{7});
  EXPECT_EQ(writer.samples_written(), 1u);
}

}  // namespace
}  // namespace cdc::dds
