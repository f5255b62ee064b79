#include "launch_support.hpp"

#include "temp_dir.hpp"

#include <signal.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace cdc::test {

std::string env_or_empty(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

bool can_use_netns() {
  if (geteuid() != 0) return false;
  const std::string probe = "cdc-test-probe-" + std::to_string(getpid());
  if (std::system(("ip netns add " + probe + " 2>/dev/null").c_str()) != 0) return false;
  return std::system(("ip netns delete " + probe).c_str()) == 0;
}

std::set<std::string> netns_list() {
  std::set<std::string> out;
  FILE* f = popen("ip netns list 2>/dev/null", "r");
  if (!f) return out;
  char line[512];
  while (fgets(line, sizeof line, f)) {
    std::string s(line);
    s = s.substr(0, s.find_first_of(" \n"));
    if (!s.empty()) out.insert(s);
  }
  pclose(f);
  return out;
}

std::vector<std::string> launch_leftovers(const std::filesystem::path& run) {
  std::vector<std::string> out;
  std::istringstream procs(read_file(run / "processes.txt"));
  std::string name;
  pid_t pid = 0;
  while (procs >> name >> pid) {
    if (kill(pid, 0) == 0) out.push_back(name + " (pid " + std::to_string(pid) + ") still runs");
  }
  const std::set<std::string> now = netns_list();
  std::istringstream nss(read_file(run / "namespaces.txt"));
  size_t recorded = 0;
  for (std::string ns; nss >> ns; ++recorded) {
    if (now.count(ns)) out.push_back("namespace " + ns + " left behind");
  }
  if (recorded == 0) out.push_back("the launcher recorded no namespaces");
  return out;
}

}  // namespace cdc::test
