#include "cdc/loop_closure/loop_numbering.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>

namespace cdc::loops {
namespace {

namespace fs = std::filesystem;

struct StateDir {
  fs::path dir = fs::temp_directory_path() / ("cdc_loop_numbering_" + std::to_string(::getpid()) + "_" +
                                              ::testing::UnitTest::GetInstance()->current_test_info()->name());
  StateDir() { fs::create_directories(dir); }
  ~StateDir() { fs::remove_all(dir); }
  std::string file() const { return (dir / "loop-closure-0.state").string(); }
};

TEST(LoopNumbering, WithoutAStateFileEachIncarnationCountsFromZero) {
  LoopNumbering n;
  EXPECT_EQ(n.take(7), 0u);
  EXPECT_EQ(n.take(7), 1u);
  EXPECT_EQ(n.take(9), 0u) << "a new incarnation is a new session at the central";
  EXPECT_EQ(n.take(9), 1u);
  EXPECT_FALSE(n.stored().has_value());
}

TEST(LoopNumbering, ARestartUnderTheSameIncarnationGoesOnWhereTheLastStopped) {
  StateDir d;
  {
    LoopNumbering first(d.file());
    EXPECT_FALSE(first.stored().has_value()) << "no file yet";
    for (uint32_t i = 0; i < 5; ++i) EXPECT_EQ(first.take(42), i);
  }  // the service dies here, without any shutdown step
  LoopNumbering second(d.file());
  ASSERT_TRUE(second.stored().has_value());
  EXPECT_EQ(second.stored()->first, 42u);
  EXPECT_EQ(second.stored()->second, 5u);
  EXPECT_EQ(second.take(42), 5u);
  EXPECT_EQ(second.take(42), 6u);
  EXPECT_EQ(second.stats().resumed, 1u);
  EXPECT_EQ(second.stats().state_errors, 0u);
  LoopNumbering third(d.file());
  EXPECT_EQ(third.take(42), 7u);
}

TEST(LoopNumbering, ARestartUnderANewIncarnationStartsAtZero) {
  StateDir d;
  {
    LoopNumbering first(d.file());
    first.take(42);
    first.take(42);
  }
  LoopNumbering second(d.file());
  EXPECT_EQ(second.take(43), 0u);
  EXPECT_EQ(second.stats().resumed, 0u);
  LoopNumbering third(d.file());
  EXPECT_EQ(third.stored()->first, 43u);
  EXPECT_EQ(third.take(43), 1u);
}

TEST(LoopNumbering, AMalformedStateFileIsNamedCountedAndNumberingStartsAtZero) {
  StateDir d;
  const std::pair<const char*, const char*> cases[] = {
      {"garbage\n", "first line is not 'cdc-loop-numbering 1'"},
      {"cdc-loop-numbering 1\nincarnation 42\n", "missing line 'next_seq N'"},
      {"cdc-loop-numbering 1\nincarnation 42\nnext_seq -3\n", "line 'next_seq -3' is not 'next_seq N'"},
      {"cdc-loop-numbering 1\nincarnation 42\nnext_seq 99999999999\n", "line 'next_seq 99999999999' is not"},
      {"cdc-loop-numbering 1\nincarnation x\nnext_seq 3\n", "line 'incarnation x' is not 'incarnation N'"},
  };
  for (const auto& [text, reason] : cases) {
    std::ofstream(d.file()) << text;
    LoopNumbering n(d.file());
    EXPECT_FALSE(n.stored().has_value()) << text;
    EXPECT_EQ(n.stats().state_errors, 1u) << text;
    EXPECT_NE(n.last_error().find(reason), std::string::npos) << n.last_error();
    EXPECT_NE(n.last_error().find(d.file()), std::string::npos) << "the file is named: " << n.last_error();
    EXPECT_EQ(n.take(42), 0u);
    LoopNumbering after(d.file());
    EXPECT_EQ(after.stats().state_errors, 0u) << "the next save replaced the bad file";
    EXPECT_EQ(after.take(42), 1u);
  }
}

TEST(LoopNumbering, AnUnwritableStateFileIsCountedAndNumberingGoesOn) {
  StateDir d;
  LoopNumbering n((d.dir / "no_such_folder" / "state").string());
  EXPECT_EQ(n.take(1), 0u);
  EXPECT_EQ(n.take(1), 1u);
  EXPECT_EQ(n.stats().save_failures, 2u);
  EXPECT_NE(n.last_error().find("cannot be written"), std::string::npos) << n.last_error();
}

}  // namespace
}  // namespace cdc::loops
