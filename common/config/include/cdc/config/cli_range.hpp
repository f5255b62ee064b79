// A CLI11 check for every numeric command-line option: the text must be a finite number in [lo, hi].
// CLI11's own Range and PositiveNumber let NaN through (every comparison with NaN is false) and an unsigned
// option reads "-1" as its largest value; this check parses the text as a double first, so both are refused
// with the option's name, the value and the range.
#pragma once

#include "cdc/config/reader.hpp"

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>

namespace cdc::config {

inline CLI::Validator cli_range(double lo, double hi) {
  const std::string range = Reader::range_text(lo, hi);
  return CLI::Validator(
      [lo, hi, range](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end == text.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v)) {
          return "'" + text + "' is not a finite number (expected " + range + ")";
        }
        if (v < lo || v > hi) {
          return text + " is outside the allowed range (expected " + range + ")";
        }
        return {};
      },
      "NUMBER " + range.substr(3));
}

// A numeric option that shows its default in --help and takes only a finite number in [lo, hi].
template <typename T>
CLI::Option* add_number_option(CLI::App& app, const std::string& name, T& value, const std::string& description,
                               double lo, double hi) {
  return app.add_option(name, value, description)->capture_default_str()->check(cli_range(lo, hi));
}

}  // namespace cdc::config
