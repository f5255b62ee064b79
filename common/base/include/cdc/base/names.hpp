// The names of an enumeration's values, written once as a table that serves both directions:
// value -> name (to_string) and name -> value (parsing configuration and command-line words).
//
//   constexpr std::array<base::Named<Mode>, 2> kModeNames{{{Mode::kA, "a"}, {Mode::kB, "b"}}};
//   const char* to_string(Mode m) { return base::name_of(kModeNames, m, "?"); }
//   std::optional<Mode> parse_mode(std::string_view s) { return base::value_of(kModeNames, s); }
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace cdc::base {

template <class E>
struct Named {
  E value;
  const char* name;  // a string literal: to_string may hand it out as a C string
};

// The name of `value`, or `fallback` when the table does not hold it.
template <class E, std::size_t N>
constexpr const char* name_of(const std::array<Named<E>, N>& table, E value, const char* fallback) noexcept {
  for (const Named<E>& n : table) {
    if (n.value == value) return n.name;
  }
  return fallback;
}

// The value named exactly `name`, or nothing.
template <class E, std::size_t N>
constexpr std::optional<E> value_of(const std::array<Named<E>, N>& table, std::string_view name) noexcept {
  for (const Named<E>& n : table) {
    if (name == n.name) return n.value;
  }
  return std::nullopt;
}

// The names joined for an error message: "a, b or c".
template <class E, std::size_t N>
std::string names_list(const std::array<Named<E>, N>& table) {
  std::string out;
  for (std::size_t i = 0; i < N; ++i) {
    if (i > 0) out += i + 1 == N ? " or " : ", ";
    out += table[i].name;
  }
  return out;
}

}  // namespace cdc::base
