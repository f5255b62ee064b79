// cdc-eval: compares estimated trajectories with ground truth (TUM or KITTI files).
#include "cdc/base/cli.hpp"
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/eval/evaluation.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
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

struct Options {
  std::string gt_path, gt_times, format = "auto", align = "se3", json_path, svg_path, plane = "auto", title;
  std::vector<std::string> est_paths, est_times, names;
  double period_s = 0.1, max_dt_s = 0.01, rpe_delta_m = 100.0;
  size_t rpe_delta_frames = 1;

  cdc::eval::EvalOptions eval_options() const {
    cdc::eval::EvalOptions options;
    options.align = *cdc::geometry::parse_align_mode(align);
    options.max_dt_ns = static_cast<int64_t>(std::llround(max_dt_s * 1e9));
    options.rpe_delta_frames = rpe_delta_frames;
    options.rpe_delta_m = rpe_delta_m;
    return options;
  }
};

void add_options(CLI::App& app, Options& o) {
  cdc::base::add_input(app, "--gt", o.gt_path, "ground-truth trajectory file");
  cdc::base::add_input(app, "--est", o.est_paths, "estimated trajectory file (repeat for several)");
  app.add_option("--name", o.names, "display name per --est (default: file name)");
  cdc::base::add_setting(app, "--format", o.format, "file format of all inputs",
                         CLI::IsMember({"auto", "tum", "kitti"}));
  app.add_option("--gt-times", o.gt_times, "KITTI times file (seconds per line) for --gt")->check(CLI::ExistingFile);
  app.add_option("--est-times", o.est_times, "KITTI times file per --est")->check(CLI::ExistingFile);
  cdc::base::add_setting(app, "--period", o.period_s, "KITTI pose period when no times file [s]",
                         cdc::config::cli_range(0.001, 10));
  cdc::base::add_setting(app, "--max-dt", o.max_dt_s, "association tolerance between stamps [s]",
                         cdc::config::cli_range(0, 10));
  cdc::base::add_setting(app, "--align", o.align, "alignment before ATE", CLI::IsMember({"none", "se3", "sim3"}));
  cdc::base::add_setting(app, "--rpe-frames", o.rpe_delta_frames, "RPE frame delta", cdc::config::cli_range(1, 1e6));
  cdc::base::add_setting(app, "--rpe-distance", o.rpe_delta_m, "RPE distance delta [m]",
                         cdc::config::cli_range(0.001, 1e6));
  app.add_option("--json", o.json_path, "write the figures as JSON to this file ('-' for stdout)");
  app.add_option("--svg", o.svg_path, "write a top-view SVG plot to this file");
  cdc::base::add_setting(app, "--plane", o.plane, "plot plane", CLI::IsMember({"auto", "xy", "xz", "yz"}));
  app.add_option("--title", o.title, "plot title");
}

// Every --est against --gt: the table on stdout, the JSON and the plot where asked for.
void evaluate_all(const Options& o) {
  const cdc::eval::EvalOptions options = o.eval_options();
  const auto gt = load(o.gt_path, o.format, o.gt_times, o.period_s);
  std::vector<cdc::eval::Evaluation> evals;
  nlohmann::json report;
  report["ground_truth"] = o.gt_path;
  report["trajectories"] = nlohmann::json::array();
  for (size_t i = 0; i < o.est_paths.size(); ++i) {
    const std::string& path = o.est_paths[i];
    const auto est = load(path, o.format, o.est_times.empty() ? "" : o.est_times[i], o.period_s);
    const std::string name = o.names.empty() ? path.substr(path.find_last_of('/') + 1) : o.names[i];
    evals.push_back(cdc::eval::evaluate(name, est, gt, options));
    report["trajectories"].push_back(cdc::eval::to_json(evals.back(), options));
  }
  std::cout << cdc::eval::format_table(evals);
  if (o.json_path == "-") {
    std::cout << report.dump() << '\n';
  } else if (!o.json_path.empty()) {
    write_text(o.json_path, report.dump(2) + "\n");
  }
  if (!o.svg_path.empty()) {
    write_text(o.svg_path,
               cdc::eval::render_svg(evals, o.plane, o.title.empty() ? "estimate vs ground truth" : o.title));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-eval: compare estimated trajectories with ground truth.\n"
      "Files are TUM ('t x y z qx qy qz qw') or KITTI (12 numbers per line; stamps from --gt-times/--est-times or\n"
      "index * --period). Poses are matched by time stamp. Prints ATE (after alignment), RPE per frame and per\n"
      "distance, and the KITTI drift metric; optionally writes JSON and an SVG top view."};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  if (!o.names.empty() && o.names.size() != o.est_paths.size()) {
    std::cerr << "cdc-eval: --name given " << o.names.size() << " times for " << o.est_paths.size() << " --est files\n";
    return 2;
  }
  if (!o.est_times.empty() && o.est_times.size() != o.est_paths.size()) {
    std::cerr << "cdc-eval: --est-times given " << o.est_times.size() << " times for " << o.est_paths.size()
              << " --est files\n";
    return 2;
  }
  return cdc::base::run_tool("cdc-eval", [&] {
    evaluate_all(o);
    return 0;
  });
}
