// What tests of cdc-launch share: the environment the build hands them, whether this process may
// make network namespaces, and what a run left behind.
#pragma once

#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace cdc::test {

// The variable's value, or "" when it is not set.
std::string env_or_empty(const char* name);

// Root, and `ip netns add` works here.
bool can_use_netns();

// The names `ip netns list` prints.
std::set<std::string> netns_list();

// What a finished cdc-launch run left behind, one line each: a process of its processes.txt still
// running, a namespace of its namespaces.txt still there, or no namespace recorded at all.
std::vector<std::string> launch_leftovers(const std::filesystem::path& run);

}  // namespace cdc::test
