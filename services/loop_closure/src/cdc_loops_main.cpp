// cdc-loops: offline place recognition and outlier rejection tools of the loop-closure service.
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/pcm.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <iostream>

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-loops: offline tools of the loop-closure service.\n"
      "  pcm DIR   pairwise consistency maximisation over a multi-robot g2o folder (one file per robot, robot in\n"
      "            the top byte of the keys): which inter-robot loop closures to keep"};
  app.require_subcommand(1);
  std::string input;
  bool json = false, strict = false;
  double threshold = cdc::graph::PcmOptions{}.chi2_threshold;
  CLI::App* pcm = app.add_subcommand("pcm", "run PCM over a multi-robot g2o folder (or one g2o file)");
  pcm->add_option("input", input, "folder of per-robot .g2o files, or one .g2o file")->required()->check(CLI::ExistingPath);
  pcm->add_option("--chi2", threshold, "Mahalanobis threshold on a cycle (6 DoF)")->check(CLI::PositiveNumber)
      ->capture_default_str();
  pcm->add_flag("--json", json, "print one JSON object with the accepted and rejected loops (g2o vertex ids)");
  pcm->add_flag("--strict", strict, "fail on damaged lines instead of skipping them");
  CLI11_PARSE(app, argc, argv);
  try {
    std::vector<std::string> warnings;
    cdc::graph::G2oReadOptions ro;
    ro.skip_malformed = !strict;
    ro.warnings = &warnings;
    const cdc::graph::PoseGraph g = std::filesystem::is_directory(input) ? cdc::graph::read_g2o_folder(input, ro)
                                                                          : cdc::graph::read_g2o(input, ro);
    for (const auto& w : warnings) {
      std::cerr << "cdc-loops: warning: " << w << '\n';
    }
    cdc::graph::PcmOptions po;
    po.chi2_threshold = threshold;
    const cdc::graph::OutlierDecision d = cdc::graph::Pcm(po).decide(g);
    auto ids = [&](const std::vector<size_t>& factors) {
      nlohmann::json a = nlohmann::json::array();
      for (size_t f : factors) {
        a.push_back({cdc::graph::to_g2o_key(g, g.factors[f].a), cdc::graph::to_g2o_key(g, g.factors[f].b)});
      }
      return a;
    };
    if (json) {
      nlohmann::json j{{"accepted", ids(d.accepted)}, {"rejected", ids(d.rejected)}, {"skipped_lines", warnings.size()},
                       {"chi2_threshold", threshold}};
      std::cout << j.dump() << '\n';
    } else {
      std::cout << input << ": " << d.accepted.size() << " inter-robot loop closures kept, " << d.rejected.size()
                << " rejected (chi2 " << threshold << ")\n";
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "cdc-loops: " << e.what() << '\n';
    return 1;
  }
}
