// cdc-register: registers one saved sweep onto another with the front-end's point-to-plane
// registration or generalized ICP (common/odometry/registration.hpp) and prints T_target_source; with a
// reference transform it prints how far the result is from it.
#include "cdc/base/cli.hpp"
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/transform_file.hpp"
#include "cdc/odometry/registration.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

using namespace cdc;

namespace {

struct Options {
  std::string source, target, reference, method = "point-to-plane";
  // Each method's settings; the options set the method's own.
  odometry::RegistrationSettings point_to_plane, gicp = odometry::RegistrationSettings::gicp();
  std::vector<std::string> scores;
  bool json = false;
};

void add_options(CLI::App& app, Options& o) {
  odometry::RegistrationSettings &p = o.point_to_plane, &g = o.gicp;
  base::add_input(app, "source", o.source, "the sweep to move");
  base::add_input(app, "target", o.target, "the sweep it is registered onto");
  app.add_option("--reference", o.reference, "reference T_target_source (4x4, 16 numbers)")->check(CLI::ExistingFile);
  base::add_setting(app, "--source-voxel", p.voxel_m, "downsampling of the source [m]", config::cli_range(0.01, 10));
  base::add_setting(app, "--target-voxel", p.target_voxel_m, "downsampling of the target [m]",
                    config::cli_range(0.01, 10));
  base::add_setting(app, "--map-voxel", p.map_voxel_m, "voxel of the target map [m]", config::cli_range(0.01, 10));
  base::add_setting(app, "--normal-neighbours", p.neighbours, "points per source normal", config::cli_range(3, 100));
  base::add_setting(app, "--method", o.method,
                    "point-to-plane (the front-end's) or gicp (generalized ICP, plane-to-plane)",
                    CLI::IsMember({"point-to-plane", "gicp"}));
  base::add_setting(app, "--gicp-voxel", g.voxel_m, "gicp: downsampling of both clouds [m]",
                    config::cli_range(0.01, 10));
  base::add_setting(app, "--gicp-neighbours", g.neighbours, "gicp: points per covariance", config::cli_range(5, 100));
  base::add_setting(app, "--gicp-max-correspondence", g.max_correspondence_m, "gicp: correspondence distance [m]",
                    config::cli_range(0.01, 100));
  app.add_option(
         "--score", o.scores,
         "also score these transforms (4x4 files) and the result: point-to-plane RMS of the matched source points "
         "(0.1 m voxels, within 0.2 m) and how many matched, to compare references")
      ->check(CLI::ExistingFile);
  app.add_flag("--json", o.json, "print one JSON object instead");
}

nlohmann::json score_of(const std::string& name, const odometry::AlignmentScore& a) {
  return {{"transform", name},
          {"matched", a.matched},
          {"within_1cm", a.within_1cm},
          {"within_2cm", a.within_2cm},
          {"source_points", a.source_points},
          {"rms_point_to_plane_m", a.rms_point_to_plane_m}};
}

// The registration, its distance to the reference and the scores, as one JSON object; throws on
// unreadable files and on sweeps too small to register.
nlohmann::json register_sweeps(const Options& o) {
  const auto src = io::read_cloud_xyz(o.source), tgt = io::read_cloud_xyz(o.target);
  if (src.size() < 100 || tgt.size() < 100) {
    throw std::runtime_error("too few points (" + std::to_string(src.size()) + " in the source, " +
                             std::to_string(tgt.size()) + " in the target)");
  }
  const odometry::RegistrationResult r = odometry::register_clouds(src, tgt, Eigen::Isometry3d::Identity(),
                                                                   o.method == "gicp" ? o.gicp : o.point_to_plane);
  nlohmann::json out{{"source_points", src.size()},
                     {"target_points", tgt.size()},
                     {"correspondences", r.correspondences},
                     {"iterations", r.iterations},
                     {"rmse_m", r.rmse},
                     {"converged", r.converged},
                     {"warnings", r.warnings}};
  std::vector<double> m;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) m.push_back(r.T_target_source.matrix()(i, j));
  }
  out["T_target_source"] = m;
  if (!o.reference.empty()) {
    const Eigen::Isometry3d e = io::read_transform_file(o.reference).inverse() * r.T_target_source;
    out["from_reference"] = {{"translation_m", e.translation().norm()},
                             {"rotation_deg", geometry::rotation_angle(e.rotation()) * 180 / M_PI}};
  }
  if (!o.scores.empty()) {
    out["scores"].push_back(score_of("result", odometry::score_alignment(src, tgt, r.T_target_source)));
    for (const std::string& f : o.scores)
      out["scores"].push_back(score_of(f, odometry::score_alignment(src, tgt, io::read_transform_file(f))));
  }
  return out;
}

void print_text(const nlohmann::json& out) {
  const std::vector<double> m = out["T_target_source"].get<std::vector<double>>();
  for (size_t i = 0; i < 4; ++i)
    std::printf("%12.8f %12.8f %12.8f %12.8f\n", m[4 * i], m[4 * i + 1], m[4 * i + 2], m[4 * i + 3]);
  std::printf("%zu source / %zu target points, %d correspondences, rmse %.4f m%s\n", out["source_points"].get<size_t>(),
              out["target_points"].get<size_t>(), out["correspondences"].get<int>(), out["rmse_m"].get<double>(),
              out["converged"].get<bool>() ? "" : ", NOT converged");
  for (const auto& w : out["warnings"]) std::printf("warning: %s\n", w.get<std::string>().c_str());
  if (out.contains("from_reference")) {
    std::printf("from the reference: %.4f m, %.4f deg\n", out["from_reference"]["translation_m"].get<double>(),
                out["from_reference"]["rotation_deg"].get<double>());
  }
  if (!out.contains("scores")) return;
  for (const auto& sc : out["scores"]) {
    std::printf("score of %s: %zu of %zu points matched, %zu within 1 cm of a plane and %zu within 2 cm, rms %.2f mm\n",
                sc["transform"].get<std::string>().c_str(), sc["matched"].get<size_t>(),
                sc["source_points"].get<size_t>(), sc["within_1cm"].get<size_t>(), sc["within_2cm"].get<size_t>(),
                sc["rms_point_to_plane_m"].get<double>() * 1e3);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-register: registers SOURCE onto TARGET (KITTI .bin, .pcd or .ply) from the\n"
      "identity, with the front-end's point-to-plane registration (coarse to fine) or generalized ICP, and prints\n"
      "T_target_source (4x4, row by row). --reference FILE (16 numbers) also prints the difference to a reference\n"
      "transform; --score FILE... scores the result and the given transforms by how well they align the two sweeps."};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  return base::run_tool(
      "cdc-register",
      [&] {
        const nlohmann::json out = register_sweeps(o);
        if (o.json) {
          std::cout << out.dump() << '\n';
        } else {
          print_text(out);
        }
        return 0;
      },
      [](const std::exception&) { return 2; });
}
