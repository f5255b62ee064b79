#include "cdc/runtime/stats.hpp"

#include "cdc/dds/traffic_json.hpp"

#include <fstream>
#include <stdexcept>

namespace cdc::runtime {

nlohmann::json service_stats(nlohmann::json own, const Boundary& boundary) {
  own["rejected"] = boundary.rejected().by_topic();
  own["rejected_samples"] = boundary.rejected().total();
  own["topics"] = dds::topic_traffic_json();
  return own;
}

void write_stats(const std::string& path, nlohmann::json own, const Boundary& boundary) {
  if (path.empty()) return;
  std::ofstream out(path);
  out << service_stats(std::move(own), boundary).dump(2) << '\n';
  if (!out) throw std::runtime_error("cannot write the statistics file " + path);
}

}  // namespace cdc::runtime
