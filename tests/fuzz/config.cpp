// YAML configuration files: the generic reader (common/config) and every loader built on it (each
// service's options, the swarm files of cdc-launch). Selector % 9 picks the loader.
#include "cdc/config/reader.hpp"
#include "cdc/velodyne_driver/velodyne_driver_core.hpp"
#include "central_config.hpp"
#include "descriptor_config.hpp"
#include "frontend_config.hpp"
#include "fuzz_support.hpp"
#include "loop_config.hpp"
#include "map_config.hpp"
#include "peer_options.hpp"
#include "swarm.hpp"

#include <array>

namespace {

// Keys of every type the loaders read, nested and not, then the unknown-key check.
void generic(const std::string& path) {
  cdc::config::Reader r(path);
  double d = 0;
  int i = 0;
  uint32_t u = 0;
  bool b = false;
  std::string s;
  std::vector<double> v;
  r.get("rate", d, std::function<bool(const double&)>([](const double& x) { return x > 0; }), "positive");
  r.get("a.count", i);
  r.get("a.b.id", u);
  r.get("enabled", b);
  r.get("name", s);
  r.get("list", v);
  r.finish();
}

// The loaders, in selector order.
using Loader = void (*)(const std::string& path);
const std::array<Loader, 9> kLoaders{
    generic,
    [](const std::string& p) { (void)cdc::central::load_options(p); },
    [](const std::string& p) { (void)cdc::descriptor::load_descriptor_options(p); },
    [](const std::string& p) { (void)cdc::frontend::load_frontend_options(p); },
    [](const std::string& p) { (void)cdc::loops::load_loop_options(p); },
    [](const std::string& p) { (void)cdc::map::load_map_options(p); },
    [](const std::string& p) { (void)cdc::velodyne_driver::load_driver_config(p); },
    [](const std::string& p) { (void)cdc::peer::load_options(p); },
    [](const std::string& p) { (void)cdc::launch::load_swarm(p, cdc::fuzz::scratch_dir().string()); },
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const cdc::fuzz::Input in(data, size);
  const std::string path = cdc::fuzz::write_file("config.yaml", in.rest).string();
  cdc::fuzz::refusals_pass([&] { kLoaders[in.selector % kLoaders.size()](path); });
  return 0;
}
