// The two shapes of command-line option the tools declare most: a setting with a default and a check, and an
// input that must be given and must exist. Link cdc_base_cli (it brings CLI11).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <utility>

namespace cdc::base {

// A setting: --help shows its current value as the default, and `check` guards what is given.
template <class T>
CLI::Option* add_setting(CLI::App& app, const std::string& name, T& value, const std::string& what,
                         CLI::Validator check) {
  return app.add_option(name, value, what)->capture_default_str()->check(std::move(check));
}

// A required input: `exists` is CLI::ExistingFile, CLI::ExistingDirectory or CLI::ExistingPath.
template <class T>
CLI::Option* add_input(CLI::App& app, const std::string& name, T& value, const std::string& what,
                       CLI::Validator exists = CLI::ExistingFile) {
  return app.add_option(name, value, what)->required()->check(std::move(exists));
}

}  // namespace cdc::base
