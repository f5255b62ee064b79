// The exit convention of the command-line tools: what their main() does with an exception.
#pragma once

#include <exception>
#include <iostream>
#include <string_view>

namespace cdc::base {

// Runs a tool's work, `body` returning the exit code. An exception from it is printed on stderr as
// "<tool>: <what>" and ends the tool with failure_code(e), or 1 without one.
template <class Body>
int run_tool(std::string_view tool, Body&& body, int (*failure_code)(const std::exception&) = nullptr) {
  try {
    return body();
  } catch (const std::exception& e) {
    std::cerr << tool << ": " << e.what() << '\n';
    return failure_code != nullptr ? failure_code(e) : 1;
  }
}

}  // namespace cdc::base
