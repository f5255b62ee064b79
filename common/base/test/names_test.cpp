#include "cdc/base/names.hpp"

#include <gtest/gtest.h>

namespace cdc::base {
namespace {

enum class Colour { kRed, kGreen, kBlue, kUnnamed };
constexpr std::array<Named<Colour>, 3> kColours{
    {{Colour::kRed, "red"}, {Colour::kGreen, "green"}, {Colour::kBlue, "blue"}}};

TEST(Names, NameOfEveryValueAndFallback) {
  EXPECT_STREQ(name_of(kColours, Colour::kRed, "?"), "red");
  EXPECT_STREQ(name_of(kColours, Colour::kBlue, "?"), "blue");
  EXPECT_STREQ(name_of(kColours, Colour::kUnnamed, "?"), "?");
  static_assert(std::string_view(name_of(kColours, Colour::kGreen, "?")) == "green");
}

TEST(Names, ValueOfExactNamesOnly) {
  EXPECT_EQ(value_of(kColours, "green"), Colour::kGreen);
  EXPECT_EQ(value_of(kColours, std::string("blue")), Colour::kBlue);
  EXPECT_FALSE(value_of(kColours, "Green").has_value());
  EXPECT_FALSE(value_of(kColours, "").has_value());
  static_assert(value_of(kColours, "red") == Colour::kRed);
}

TEST(Names, ListForMessages) {
  EXPECT_EQ(names_list(kColours), "red, green or blue");
  constexpr std::array<Named<Colour>, 1> kOne{{{Colour::kRed, "red"}}};
  EXPECT_EQ(names_list(kOne), "red");
}

}  // namespace
}  // namespace cdc::base
