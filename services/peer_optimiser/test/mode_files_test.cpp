// --mode-out: the transition timeline and the launcher's FILE.now, in the formats deploy/launch
// reads; and Period, the node's clock for what it does periodically.
#include "../src/mode_files.hpp"
#include "../src/period.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace cdc::peer {
namespace {

namespace fs = std::filesystem;

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class ModeFilesTest : public test::TempDirTest {
 protected:
  ModeFilesTest() : TempDirTest("mode_files") {}
};

TEST_F(ModeFilesTest, TimelineHasOneLinePerTransition) {
  const fs::path csv = dir_ / "modes.csv";
  ModeFiles files(csv.string());
  EXPECT_EQ(read(csv), "wall_ns,sim_ns,robot,from,to,reason,distance_m,keyframes\n") << "the header at once";
  files.transition(Transition{Mode::kDistributed, Mode::kCentralized, SwitchReason::kBackInRange, Nanos{0}, 12.5}, 100,
                   200, 1, 40);
  files.transition(Transition{Mode::kCentralized, Mode::kDistributed, SwitchReason::kLivelinessLost, Nanos{0}, {}}, 300,
                   400, 1, 41);
  EXPECT_EQ(read(csv),
            "wall_ns,sim_ns,robot,from,to,reason,distance_m,keyframes\n"
            "100,200,1,DISTRIBUTED,CENTRALIZED,back in range,12.500000,40\n"
            "300,400,1,CENTRALIZED,DISTRIBUTED,liveliness lost,,41\n");
}

TEST_F(ModeFilesTest, NowFileIsReplacedWhole) {
  const fs::path csv = dir_ / "modes.csv";
  const ModeFiles files(csv.string());
  files.now(BackendState{Mode::kCentralized, 40, 3, true, 38});
  EXPECT_EQ(read(dir_ / "modes.csv.now"), "CENTRALIZED 40 3 1 39\n");
  files.now(BackendState{Mode::kDistributed, 41, 4, false, -1});
  EXPECT_EQ(read(dir_ / "modes.csv.now"), "DISTRIBUTED 41 4 0 0\n");
  EXPECT_FALSE(fs::exists(dir_ / "modes.csv.now.tmp"));
}

TEST_F(ModeFilesTest, NoPathWritesNothingAndABadOneIsNamed) {
  ModeFiles none("");
  none.transition(Transition{}, 1, 2, 0, 0);
  none.now(BackendState{});
  EXPECT_TRUE(fs::is_empty(dir_));
  try {
    ModeFiles bad((dir_ / "missing" / "modes.csv").string());
    FAIL() << "an unwritable timeline must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing/modes.csv"), std::string::npos) << e.what();
  }
}

TEST(Period, DueAtFirstThenEveryPeriodAndAtOnceWhenExpired) {
  using namespace std::chrono_literals;
  const Period::Clock::time_point t0{std::chrono::seconds(100)};
  Period p(250ms);
  EXPECT_TRUE(p.due(t0));
  p.done(t0);
  EXPECT_FALSE(p.due(t0 + 249ms));
  EXPECT_TRUE(p.due(t0 + 250ms));
  p.expire();
  EXPECT_TRUE(p.due(t0 + 1ms));
}

}  // namespace
}  // namespace cdc::peer
