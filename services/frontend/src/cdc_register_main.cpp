// cdc-register: registers one saved sweep onto another with the front-end's point-to-plane
// registration or generalized ICP (common/odometry/pair_registration.hpp) and prints T_target_source; with a reference
// transform it prints how far the result is from it.
#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/pair_registration.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>

using namespace cdc;

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-register: registers SOURCE onto TARGET (KITTI .bin, binary .pcd or binary little-endian .ply) from the\n"
      "identity, with the front-end's point-to-plane registration (coarse to fine) or generalized ICP, and prints\n"
      "T_target_source (4x4, row by row). --reference FILE (16 numbers) also prints the difference to a reference\n"
      "transform; --score FILE... scores the result and the given transforms by how well they align the two sweeps."};
  std::string source, target, reference;
  odometry::PairRegistrationParams p;
  bool json = false;
  app.add_option("source", source, "the sweep to move")->required()->check(CLI::ExistingFile);
  app.add_option("target", target, "the sweep it is registered onto")->required()->check(CLI::ExistingFile);
  app.add_option("--reference", reference, "reference T_target_source (4x4, 16 numbers)")->check(CLI::ExistingFile);
  app.add_option("--source-voxel", p.source_voxel_m, "downsampling of the source [m]")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--target-voxel", p.target_voxel_m, "downsampling of the target [m]")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--map-voxel", p.map_voxel_m, "voxel of the target map [m]")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--normal-neighbours", p.normal_neighbours, "points per source normal")->capture_default_str()->check(CLI::Range(3, 100));
  std::string method = "point-to-plane";
  app.add_option("--method", method, "point-to-plane (the front-end's) or gicp (generalized ICP, plane-to-plane)")
      ->capture_default_str()
      ->check(CLI::IsMember({"point-to-plane", "gicp"}));
  app.add_option("--gicp-voxel", p.gicp_voxel_m, "gicp: downsampling of both clouds [m]")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--gicp-neighbours", p.gicp_neighbours, "gicp: points per covariance")->capture_default_str()->check(CLI::Range(5, 100));
  app.add_option("--gicp-max-correspondence", p.gicp_max_correspondence_m, "gicp: correspondence distance [m]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  std::vector<std::string> scores;
  app.add_option("--score", scores,
                 "also score these transforms (4x4 files) and the result: point-to-plane RMS of the matched source points "
                 "(0.1 m voxels, within 0.2 m) and how many matched, to compare references")
      ->check(CLI::ExistingFile);
  app.add_flag("--json", json, "print one JSON object instead");
  CLI11_PARSE(app, argc, argv);
  p.method = method == "gicp" ? odometry::PairMethod::kGicp : odometry::PairMethod::kPointToPlane;
  try {
    const auto src = odometry::read_cloud_file(source), tgt = odometry::read_cloud_file(target);
    if (src.size() < 100 || tgt.size() < 100) {
      std::cerr << "cdc-register: too few points (" << src.size() << " in the source, " << tgt.size() << " in the target)\n";
      return 2;
    }
    const odometry::RegistrationOutput r = odometry::register_pair(src, tgt, Eigen::Isometry3d::Identity(), p);
    nlohmann::json out{{"source_points", src.size()}, {"target_points", tgt.size()}, {"correspondences", r.correspondences},
                       {"rmse_m", r.rmse}, {"converged", r.converged}};
    std::vector<double> m;
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) m.push_back(r.T_map_sensor.matrix()(i, j));
    }
    out["T_target_source"] = m;
    if (!reference.empty()) {
      const Eigen::Isometry3d e = odometry::read_matrix_file(reference).inverse() * r.T_map_sensor;
      out["from_reference"] = {{"translation_m", e.translation().norm()},
                               {"rotation_deg", geometry::rotation_angle(e.rotation()) * 180 / M_PI}};
    }
    if (!scores.empty()) {
      auto score = [&](const std::string& name, const Eigen::Isometry3d& T) {
        const odometry::AlignmentScore a = odometry::score_alignment(src, tgt, T);
        out["scores"].push_back({{"transform", name}, {"matched", a.matched}, {"within_1cm", a.within_1cm}, {"within_2cm", a.within_2cm}, {"source_points", a.source_points},
                                 {"rms_point_to_plane_m", a.rms_point_to_plane_m}});
      };
      score("result", r.T_map_sensor);
      for (const std::string& f : scores) score(f, odometry::read_matrix_file(f));
    }
    if (json) {
      std::cout << out.dump() << '\n';
      return 0;
    }
    for (size_t i = 0; i < 4; ++i) {
      std::printf("%12.8f %12.8f %12.8f %12.8f\n", m[4 * i], m[4 * i + 1], m[4 * i + 2], m[4 * i + 3]);
    }
    std::printf("%zu source / %zu target points, %d correspondences, rmse %.4f m%s\n", src.size(), tgt.size(),
                r.correspondences, r.rmse, r.converged ? "" : ", NOT converged");
    if (out.contains("from_reference")) {
      std::printf("from the reference: %.4f m, %.4f deg\n", out["from_reference"]["translation_m"].get<double>(),
                  out["from_reference"]["rotation_deg"].get<double>());
    }
    if (out.contains("scores")) {
      for (const auto& sc : out["scores"]) {
        std::printf("score of %s: %zu of %zu points matched, %zu within 1 cm of a plane and %zu within 2 cm, rms %.2f mm\n",
                    sc["transform"].get<std::string>().c_str(), sc["matched"].get<size_t>(), sc["source_points"].get<size_t>(),
                    sc["within_1cm"].get<size_t>(), sc["within_2cm"].get<size_t>(), sc["rms_point_to_plane_m"].get<double>() * 1e3);
      }
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "cdc-register: " << e.what() << '\n';
    return 2;
  }
}
