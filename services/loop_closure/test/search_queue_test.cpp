#include "cdc/loop_closure/search_queue.hpp"
#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace cdc::loops {
namespace {

using std::chrono::seconds;

using test::desc;

// "robot/id" of every descriptor popped until the queue is empty.
std::vector<std::string> drain(SearchQueue& q) {
  std::vector<std::string> out;
  while (auto d = q.pop()) out.push_back(std::to_string(d->robot) + "/" + std::to_string(d->id));
  return out;
}

TEST(SearchQueue, APeersBacklogNoLongerHoldsBackTheOwnRobotsNewKeyframes) {
  SearchQueue q;
  for (uint32_t id = 0; id < 5; ++id) q.push(desc(2, id), Nanos(0));  // a rejoining peer's backlog
  q.push(desc(0, 40), Nanos(0));                                      // then this robot's own new keyframes
  q.push(desc(0, 41), Nanos(0));
  EXPECT_EQ(q.size(), 7u);
  EXPECT_EQ(q.size(2), 5u);
  // Served in turn, each robot's descriptors in their own order: the own keyframes come first and
  // third, not after the whole backlog.
  EXPECT_EQ(drain(q), (std::vector<std::string>{"0/40", "2/0", "0/41", "2/1", "2/2", "2/3", "2/4"}));
  EXPECT_TRUE(q.empty());
  EXPECT_FALSE(q.pop().has_value());
}

TEST(SearchQueue, TurnsGoOnAfterTheLastRobotServedAndWrapAround) {
  SearchQueue q;
  q.push(desc(1, 0), Nanos(0));
  ASSERT_EQ(q.pop()->robot, 1u);
  q.push(desc(0, 7), Nanos(0));
  q.push(desc(2, 3), Nanos(0));
  q.push(desc(1, 1), Nanos(0));
  EXPECT_EQ(drain(q), (std::vector<std::string>{"2/3", "0/7", "1/1"}));
}

TEST(SearchQueue, LatencyRunsFromTheLaterDescriptorOfTheLoop) {
  SearchQueue q;
  q.push(desc(0, 10), seconds(3));
  q.push(desc(1, 20), seconds(5));
  LoopOut l;
  l.robot_a = 0;
  l.keyframe_a = 10;
  l.robot_b = 1;
  l.keyframe_b = 20;
  ASSERT_TRUE(q.latency_s(l, seconds(9)).has_value());
  EXPECT_DOUBLE_EQ(*q.latency_s(l, seconds(9)), 4.0);
  drain(q);  // searched: still remembered
  EXPECT_DOUBLE_EQ(*q.latency_s(l, seconds(9)), 4.0);
  l.keyframe_b = 21;  // never queued here
  EXPECT_FALSE(q.latency_s(l, seconds(9)).has_value());
}

}  // namespace
}  // namespace cdc::loops
