// cdc-eval: compares estimated trajectories with ground truth (TUM or KITTI files).
#include "cdc/eval/evaluation.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <iostream>

namespace {

using cdc::geometry::TrajectoryFormat;

struct Input {
  std::string path;
  std::string times;  // KITTI only
};

cdc::geometry::Trajectory load(const std::string& path, const std::string& format_name, const std::string& times_path,
                               double period_s) {
  TrajectoryFormat format;
  if (format_name == "auto") {
    format = cdc::geometry::detect_format(path);
  } else {
    format = *cdc::geometry::parse_format(format_name);
  }
  if (format == TrajectoryFormat::kTum) {
    if (!times_path.empty()) {
      throw std::runtime_error(path + ": a times file applies to KITTI files only (TUM files carry stamps)");
    }
    return cdc::geometry::read_tum(path);
  }
  const auto period_ns = static_cast<int64_t>(std::llround(period_s * 1e9));
  if (!times_path.empty()) {
    const std::vector<int64_t> stamps = cdc::geometry::read_times(times_path);
    return cdc::geometry::read_kitti(path, &stamps, period_ns);
  }
  return cdc::geometry::read_kitti(path, nullptr, period_ns);
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out || !(out << text)) {
    throw std::runtime_error(path + ": cannot write file");
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-eval: compare estimated trajectories with ground truth.\n"
      "Files are TUM ('t x y z qx qy qz qw') or KITTI (12 numbers per line; stamps from --gt-times/--est-times or\n"
      "index * --period). Poses are matched by time stamp. Prints ATE (after alignment), RPE per frame and per\n"
      "distance, and the KITTI drift metric; optionally writes JSON and an SVG top view."};
  std::string gt_path, gt_times, format = "auto", align = "se3", json_path, svg_path, plane = "auto", title;
  std::vector<std::string> est_paths, est_times, names;
  double period_s = 0.1, max_dt_s = 0.01, rpe_delta_m = 100.0;
  size_t rpe_delta_frames = 1;
  app.add_option("--gt", gt_path, "ground-truth trajectory file")->required()->check(CLI::ExistingFile);
  app.add_option("--est", est_paths, "estimated trajectory file (repeat for several)")->required()->check(CLI::ExistingFile);
  app.add_option("--name", names, "display name per --est (default: file name)");
  app.add_option("--format", format, "file format of all inputs")->check(CLI::IsMember({"auto", "tum", "kitti"}))
      ->capture_default_str();
  app.add_option("--gt-times", gt_times, "KITTI times file (seconds per line) for --gt")->check(CLI::ExistingFile);
  app.add_option("--est-times", est_times, "KITTI times file per --est")->check(CLI::ExistingFile);
  app.add_option("--period", period_s, "KITTI pose period when no times file [s]")->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-dt", max_dt_s, "association tolerance between stamps [s]")->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--align", align, "alignment before ATE")->check(CLI::IsMember({"none", "se3", "sim3"}))
      ->capture_default_str();
  app.add_option("--rpe-frames", rpe_delta_frames, "RPE frame delta")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--rpe-distance", rpe_delta_m, "RPE distance delta [m]")->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--json", json_path, "write the figures as JSON to this file ('-' for stdout)");
  app.add_option("--svg", svg_path, "write a top-view SVG plot to this file");
  app.add_option("--plane", plane, "plot plane")->check(CLI::IsMember({"auto", "xy", "xz", "yz"}))->capture_default_str();
  app.add_option("--title", title, "plot title");
  CLI11_PARSE(app, argc, argv);

  if (!names.empty() && names.size() != est_paths.size()) {
    std::cerr << "cdc-eval: --name given " << names.size() << " times for " << est_paths.size() << " --est files\n";
    return 2;
  }
  if (!est_times.empty() && est_times.size() != est_paths.size()) {
    std::cerr << "cdc-eval: --est-times given " << est_times.size() << " times for " << est_paths.size()
              << " --est files\n";
    return 2;
  }

  try {
    cdc::eval::EvalOptions options;
    options.align = *cdc::geometry::parse_align_mode(align);
    options.max_dt_ns = static_cast<int64_t>(std::llround(max_dt_s * 1e9));
    options.rpe_delta_frames = rpe_delta_frames;
    options.rpe_delta_m = rpe_delta_m;

    const auto gt = load(gt_path, format, gt_times, period_s);
    std::vector<cdc::eval::Evaluation> evals;
    nlohmann::json report;
    report["ground_truth"] = gt_path;
    report["trajectories"] = nlohmann::json::array();
    for (size_t i = 0; i < est_paths.size(); ++i) {
      const auto est = load(est_paths[i], format, est_times.empty() ? "" : est_times[i], period_s);
      const std::string name =
          names.empty() ? est_paths[i].substr(est_paths[i].find_last_of('/') + 1) : names[i];
      evals.push_back(cdc::eval::evaluate(name, est, gt, options));
      report["trajectories"].push_back(cdc::eval::to_json(evals.back(), options));
    }
    std::cout << cdc::eval::format_table(evals);
    if (!json_path.empty()) {
      if (json_path == "-") {
        std::cout << report.dump() << '\n';
      } else {
        write_text(json_path, report.dump(2) + "\n");
      }
    }
    if (!svg_path.empty()) {
      write_text(svg_path, cdc::eval::render_svg(evals, plane, title.empty() ? "estimate vs ground truth" : title));
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "cdc-eval: " << e.what() << '\n';
    return 1;
  }
}
