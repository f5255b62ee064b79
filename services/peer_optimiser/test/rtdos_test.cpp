#include "cdc/peer_optimiser/rtdos.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace cdc::peer {
namespace {

using namespace std::chrono_literals;

RtdosParams params() {
  RtdosParams p;
  p.range_m = 100;
  p.hysteresis_m = 10;
  p.dwell = 3s;
  p.mask = 2s;
  return p;
}

RtdosInput at(Nanos t, bool alive, std::optional<double> d) { return RtdosInput{t, alive, d}; }

// Drives the machine to CENTRALIZED at time t0 + dwell (central alive, distance 50 m).
Rtdos centralized_at_3s() {
  Rtdos m(params());
  EXPECT_FALSE(m.update(at(0s, true, 50.0)));
  EXPECT_FALSE(m.update(at(2s, true, 50.0)));
  auto t = m.update(at(3s, true, 50.0));
  EXPECT_TRUE(t);
  EXPECT_EQ(m.mode(), Mode::kCentralized);
  return m;
}

// Leaves CENTRALIZED on `leave`; then none of `quiet` switches, and `back` switches back in range.
void expect_return(Rtdos& m, const RtdosInput& leave, const std::vector<RtdosInput>& quiet, const RtdosInput& back) {
  ASSERT_TRUE(m.update(leave));
  for (const RtdosInput& in : quiet) {
    EXPECT_FALSE(m.update(in)) << "switched at " << in.now.count() << " ns";
  }
  const auto t = m.update(back);
  ASSERT_TRUE(t);
  EXPECT_EQ(t->reason, SwitchReason::kBackInRange);
}

TEST(Rtdos, StartsDistributedAndJoinsAfterTheDwell) {
  Rtdos m(params());
  EXPECT_EQ(m.mode(), Mode::kDistributed);
  EXPECT_EQ(m.last_reason(), SwitchReason::kStartup);
  EXPECT_FALSE(m.update(at(0s, false, std::nullopt)));  // no central yet
  EXPECT_FALSE(m.update(at(1s, true, std::nullopt)));   // alive: the dwell starts now
  EXPECT_FALSE(m.update(at(3900ms, true, std::nullopt)));
  const auto t = m.update(at(4s, true, std::nullopt));
  ASSERT_TRUE(t);
  EXPECT_EQ(t->from, Mode::kDistributed);
  EXPECT_EQ(t->to, Mode::kCentralized);
  EXPECT_EQ(t->reason, SwitchReason::kBackInRange);
  EXPECT_EQ(t->when, Nanos(4s));
  EXPECT_EQ(m.transitions(), 1u);
}

TEST(Rtdos, LivelinessLossSwitchesAtOnceEvenInsideTheMask) {
  Rtdos m = centralized_at_3s();
  const auto t = m.update(at(3100ms, false, 50.0));  // 100 ms after the last switch: masked for range
  ASSERT_TRUE(t);
  EXPECT_EQ(t->to, Mode::kDistributed);
  EXPECT_EQ(t->reason, SwitchReason::kLivelinessLost);
}

TEST(Rtdos, OutOfRangeSwitchesAtCr0) {
  Rtdos m = centralized_at_3s();
  EXPECT_FALSE(m.update(at(10s, true, 99.9)));
  EXPECT_FALSE(m.update(at(11s, true, 100.0)));  // not beyond CR_0
  const auto t = m.update(at(12s, true, 100.1));
  ASSERT_TRUE(t);
  EXPECT_EQ(t->reason, SwitchReason::kOutOfRange);
  EXPECT_DOUBLE_EQ(*t->distance_m, 100.1);
}

TEST(Rtdos, MaskBlocksRangeTriggersRightAfterASwitch) {
  Rtdos m = centralized_at_3s();                // switched at 3 s; mask until 5 s
  EXPECT_FALSE(m.update(at(4s, true, 150.0)));  // out of range but masked
  const auto t = m.update(at(5s, true, 150.0));
  ASSERT_TRUE(t);
  EXPECT_EQ(t->reason, SwitchReason::kOutOfRange);
}

// The way back to CENTRALIZED, case by case: out on `leave`, none of `quiet` switches, `back` does.
struct ReturnCase {
  const char* needs;
  RtdosInput leave;
  std::vector<RtdosInput> quiet;
  RtdosInput back;
};

TEST(Rtdos, ReturnNeedsHysteresisAContinuousDwellAndALiveCentral) {
  const std::vector<ReturnCase> cases{
      // Out at 10 s. At 95 m it is below CR_0 but not below CR_0 - hysteresis; at 89 m (31 s) the dwell
      // starts; leaving the inner zone (91 m at 33.5 s) restarts it from 34 s, and it completes at 37 s.
      {"hysteresis and a continuous dwell",
       at(10s, true, 120.0),
       {at(20s, true, 95.0), at(30s, true, 95.0), at(31s, true, 89.0), at(33s, true, 89.0), at(33500ms, true, 91.0),
        at(34s, true, 80.0), at(36900ms, true, 80.0)},
       at(37s, true, 80.0)},
      // Lost at 4 s. In range but with no central until 21 s, when the dwell starts; losing the central
      // during the dwell (23.5 s) restarts it, and it completes 3 s after the central is back.
      {"a live central",
       at(4s, false, 50.0),
       {at(10s, false, 50.0), at(20s, false, 50.0), at(21s, true, 50.0), at(23s, true, 50.0), at(23500ms, false, 50.0),
        at(24s, true, 50.0), at(26s, true, 50.0)},
       at(27s, true, 50.0)},
  };
  for (const ReturnCase& c : cases) {
    SCOPED_TRACE(std::string("return needs ") + c.needs);
    Rtdos m = centralized_at_3s();
    expect_return(m, c.leave, c.quiet, c.back);
  }
}

TEST(Rtdos, NoFlappingOnADistanceOscillatingAroundCr0) {
  Rtdos m = centralized_at_3s();
  std::vector<Transition> seen;
  // 60 s of distance 100 +- 4 m, 10 Hz: it crosses CR_0 every half period.
  for (int i = 0; i < 600; ++i) {
    const Nanos t = 10s + Nanos(i * 100ms);
    const double d = 100.0 + 4.0 * std::sin(0.5 * i);
    if (auto tr = m.update(at(t, true, d))) {
      seen.push_back(*tr);
    }
  }
  ASSERT_EQ(seen.size(), 1u);  // out once, never back: it never went below CR_0 - hysteresis
  EXPECT_EQ(seen[0].reason, SwitchReason::kOutOfRange);
  EXPECT_EQ(m.mode(), Mode::kDistributed);
}

TEST(Rtdos, LeavingAndReturningRepeatedlyCountsEveryTransition) {
  Rtdos m = centralized_at_3s();
  int switches = 0;
  for (int cycle = 0; cycle < 3; ++cycle) {
    const Nanos base = Nanos(std::chrono::seconds(10 + 30 * cycle));
    switches += m.update(at(base, true, 150.0)) ? 1 : 0;  // out
    for (int s = 1; s <= 10; ++s) {
      switches += m.update(at(base + Nanos(std::chrono::seconds(s)), true, 50.0)) ? 1 : 0;  // back after dwell
    }
  }
  EXPECT_EQ(switches, 6);
  EXPECT_EQ(m.transitions(), 7u);  // plus the initial join
  EXPECT_EQ(m.mode(), Mode::kCentralized);
}

// The central alive from `from` on (each update 100 ms apart) until the machine returns; the time it did.
std::optional<Nanos> return_time(Rtdos& m, Nanos from, Nanos until) {
  for (Nanos t = from; t < until; t += 100ms) {
    if (m.update(at(t, true, 50.0))) return t;
  }
  return std::nullopt;
}

TEST(Rtdos, AReturnLostAgainAtOnceDoublesTheNextDwellUpToItsLimit) {
  RtdosParams p = params();
  p.flap_window = 10s;
  p.max_dwell_factor = 4;
  Rtdos m(p);
  ASSERT_EQ(return_time(m, 0s, 10s), Nanos(3s));   // the first join waits the plain dwell
  ASSERT_TRUE(m.update(at(3500ms, false, 50.0)));  // lost at once after the first join: no flap
  EXPECT_EQ(m.dwell(), Nanos(3s));
  Nanos t = *return_time(m, 4s, 10s);
  EXPECT_EQ(t, Nanos(7s));
  for (const Nanos expected_dwell : {Nanos(6s), Nanos(12s), Nanos(12s)}) {
    ASSERT_TRUE(m.update(at(t + 500ms, false, 50.0)));  // lost half a second after the return: a flap
    EXPECT_EQ(m.dwell(), expected_dwell);
    const auto back = return_time(m, t + 1s, t + 60s);
    ASSERT_TRUE(back);
    EXPECT_EQ(*back - (t + 1s), expected_dwell);
    t = *back;
  }
  // A CENTRALIZED stint longer than the flap window: the next loss is no flap, the dwell is plain.
  EXPECT_FALSE(m.update(at(t + 10s, true, 50.0)));
  ASSERT_TRUE(m.update(at(t + 11s, false, 50.0)));
  EXPECT_EQ(m.dwell(), Nanos(3s));
}

// A link cut one second in two at the range edge: the lease sometimes outlives a cut, so the central
// looks alive through a short dwell and is lost again after the return. Damped, the robot returns
// ever more rarely instead of every few seconds.
TEST(Rtdos, ALinkFlappingFasterThanTheLeaseIsDamped) {
  Rtdos m = centralized_at_3s();
  int returns = 0;
  for (int i = 0; i < 600; ++i) {  // 60 s at 10 Hz from 10 s on
    const Nanos t = 10s + Nanos(i * 100ms);
    // Lost for 0.2 s at the start of every fourth second (the lease lapsed in one cut of four).
    const bool alive = (i % 40) >= 2;
    if (auto tr = m.update(at(t, alive, 50.0)); tr && tr->to == Mode::kCentralized) ++returns;
  }
  EXPECT_LE(returns, 2);  // undamped: a return every four seconds, 14 of them
}

}  // namespace
}  // namespace cdc::peer
