#include "cdc/eval/evaluation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace cdc::eval {
namespace {

nlohmann::json stats_json(const geometry::ErrorStats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"count", s.count}};
}

std::array<int, 2> choose_axes(const std::vector<Evaluation>& evals, const std::string& plane) {
  if (plane == "xy") return {0, 1};
  if (plane == "xz") return {0, 2};
  if (plane == "yz") return {1, 2};
  if (plane != "auto") {
    throw std::invalid_argument("plane must be xy, xz, yz or auto, not '" + plane + "'");
  }
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector3d hi = -lo;
  for (const auto& e : evals) {
    for (const auto& p : e.gt_matched) {
      lo = lo.cwiseMin(p.translation());
      hi = hi.cwiseMax(p.translation());
    }
  }
  const Eigen::Vector3d ext = hi - lo;
  std::array<int, 3> idx{0, 1, 2};
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return ext[a] > ext[b]; });
  std::array<int, 2> axes{idx[0], idx[1]};
  std::sort(axes.begin(), axes.end());
  return axes;
}

std::string xml_escape(const std::string& in) {
  std::string out;
  for (char c : in) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string fmt(double v, int prec = 3) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", prec, v);
  return buf;
}

}  // namespace

Evaluation evaluate(const std::string& name, const geometry::Trajectory& est, const geometry::Trajectory& gt,
                    const EvalOptions& options) {
  Evaluation e;
  e.name = name;
  e.estimated_poses = est.size();
  e.ground_truth_poses = gt.size();
  const auto pairs = geometry::associate(est, gt, options.max_dt_ns);
  e.matched = pairs.size();
  if (pairs.size() < 2) {
    throw std::runtime_error(
        name + ": only " + std::to_string(pairs.size()) + " poses match the ground truth in time (tolerance " +
        std::to_string(static_cast<double>(options.max_dt_ns) / 1e6) + " ms); check time stamps or --max-dt");
  }
  geometry::Poses pe, pg;
  geometry::Trajectory gt_sub;
  for (auto [i, j] : pairs) {
    pe.push_back(est[i].pose);
    pg.push_back(gt[j].pose);
    gt_sub.push_back(gt[j]);
  }
  e.gt_length_m = geometry::path_length(gt_sub);
  e.ate = geometry::compute_ate(pe, pg, options.align);
  if (!e.ate.alignment.ok) {
    throw std::runtime_error(name + ": alignment failed (too few or collinear matched positions); try --align none");
  }
  e.rpe_frames = geometry::compute_rpe_frames(pe, pg, options.rpe_delta_frames);
  e.rpe_distance = geometry::compute_rpe_distance(pe, pg, options.rpe_delta_m);
  e.drift = geometry::compute_kitti_drift(pe, pg);
  for (const auto& p : pe) {
    e.est_aligned.push_back(geometry::apply(e.ate.alignment, p));
  }
  e.gt_matched = std::move(pg);
  return e;
}

nlohmann::json to_json(const Evaluation& e, const EvalOptions& options) {
  nlohmann::json j;
  j["name"] = e.name;
  j["poses"] = {{"estimated", e.estimated_poses}, {"ground_truth", e.ground_truth_poses}, {"matched", e.matched}};
  j["gt_length_m"] = e.gt_length_m;
  j["alignment"] = {{"mode", geometry::to_string(options.align)}, {"scale", e.ate.alignment.scale}};
  j["ate_m"] = stats_json(e.ate.translation);
  j["ate_rot_deg"] = stats_json(e.ate.rotation_deg);
  j["rpe_frames"] = {{"delta", e.rpe_frames.delta},
                     {"trans_m", stats_json(e.rpe_frames.translation)},
                     {"rot_deg", stats_json(e.rpe_frames.rotation_deg)}};
  j["rpe_distance"] = {{"delta", e.rpe_distance.delta},
                       {"trans_m", stats_json(e.rpe_distance.translation)},
                       {"rot_deg", stats_json(e.rpe_distance.rotation_deg)}};
  j["kitti_drift"] = {{"trans_pct", e.drift.translation_pct},
                      {"rot_deg_per_100m", e.drift.rotation_deg_per_100m},
                      {"segments", e.drift.segments}};
  return j;
}

std::string format_table(const std::vector<Evaluation>& evaluations) {
  std::ostringstream s;
  char line[512];
  std::snprintf(line, sizeof line, "%-24s %7s %9s %9s %9s %9s %10s %10s %9s %11s\n", "trajectory", "matched",
                "length_m", "ATE_rmse", "ATE_mean", "ATE_max", "RPE1_t_m", "RPE1_r_deg", "drift_%", "drift_d/100m");
  s << line;
  for (const auto& e : evaluations) {
    std::snprintf(line, sizeof line, "%-24s %7zu %9s %9s %9s %9s %10s %10s %9s %11s\n", e.name.c_str(), e.matched,
                  fmt(e.gt_length_m, 1).c_str(), fmt(e.ate.translation.rmse, 4).c_str(),
                  fmt(e.ate.translation.mean, 4).c_str(), fmt(e.ate.translation.max, 4).c_str(),
                  fmt(e.rpe_frames.translation.rmse, 4).c_str(), fmt(e.rpe_frames.rotation_deg.rmse, 4).c_str(),
                  e.drift.segments > 0 ? fmt(e.drift.translation_pct, 3).c_str() : "n/a",
                  e.drift.segments > 0 ? fmt(e.drift.rotation_deg_per_100m, 4).c_str() : "n/a");
    s << line;
  }
  return s.str();
}

const char* plot_color(size_t k) {
  static const std::array<const char*, 6> kColors = {"#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
  return kColors[k % kColors.size()];
}

namespace {

constexpr double kPlotSize = 800, kPlotMargin = 60;  // [px]

// Where the plot puts a point: the two axes drawn, and metres to pixels so that every path fits (y up).
class PlotFrame {
 public:
  PlotFrame(const std::vector<Evaluation>& evaluations, const std::string& plane)
      : axes_(choose_axes(evaluations, plane)) {
    for (const auto& e : evaluations) {
      extend(e.gt_matched);
      extend(e.est_aligned);
    }
    span_ = std::max({xmax_ - xmin_, ymax_ - ymin_, 1e-6});
    scale_ = (kPlotSize - 2 * kPlotMargin) / span_;
  }

  double span() const { return span_; }
  double scale() const { return scale_; }
  char axis_name(int k) const { return "xyz"[axes_[static_cast<size_t>(k)]]; }
  double px(const Eigen::Vector3d& p) const { return kPlotMargin + (p[axes_[0]] - xmin_) * scale_; }
  double py(const Eigen::Vector3d& p) const { return kPlotSize - kPlotMargin - (p[axes_[1]] - ymin_) * scale_; }

  std::string polyline(const geometry::Poses& ps, const char* color, const char* dash) const {
    std::ostringstream s;
    s << "<polyline fill=\"none\" stroke=\"" << color << "\" stroke-width=\"1.5\"" << dash << " points=\"";
    for (const auto& p : ps) s << fmt(px(p.translation()), 1) << ',' << fmt(py(p.translation()), 1) << ' ';
    s << "\"/>\n";
    return s.str();
  }

 private:
  void extend(const geometry::Poses& ps) {
    for (const auto& p : ps) {
      xmin_ = std::min(xmin_, p.translation()[axes_[0]]);
      xmax_ = std::max(xmax_, p.translation()[axes_[0]]);
      ymin_ = std::min(ymin_, p.translation()[axes_[1]]);
      ymax_ = std::max(ymax_, p.translation()[axes_[1]]);
    }
  }

  std::array<int, 2> axes_;
  double xmin_ = std::numeric_limits<double>::max(), ymin_ = xmin_, xmax_ = -xmin_, ymax_ = -xmin_;
  double span_ = 0, scale_ = 0;
};

// A round length near a fifth of the span, drawn at the bottom left with the axes' directions.
void draw_scale_bar(std::ostream& svg, const PlotFrame& f) {
  const double h = kPlotSize, bar = std::pow(10.0, std::floor(std::log10(f.span() / 5.0)));
  svg << "<line x1=\"" << kPlotMargin << "\" y1=\"" << h - 20 << "\" x2=\"" << kPlotMargin + bar * f.scale()
      << "\" y2=\"" << h - 20 << "\" stroke=\"black\" stroke-width=\"2\"/>\n"
      << "<text x=\"" << kPlotMargin << "\" y=\"" << h - 5 << "\">" << fmt(bar, bar < 1 ? 2 : 0) << " m ("
      << f.axis_name(0) << " right, " << f.axis_name(1) << " up)</text>\n";
}

// Every estimate over its ground truth, each with a legend entry (three per row) below the plot.
void draw_estimates(std::ostream& svg, const PlotFrame& f, const std::vector<Evaluation>& evaluations,
                    double legend_y) {
  size_t k = 0;
  for (const auto& e : evaluations) {
    const char* color = plot_color(k);
    const double column = 260 * static_cast<double>(k % 3);
    svg << f.polyline(e.gt_matched, "#555555", " stroke-dasharray=\"4 3\"");
    svg << f.polyline(e.est_aligned, color, "");
    svg << "<rect x=\"" << kPlotMargin + column << "\" y=\"" << legend_y - 10 << "\" width=\"14\" height=\"4\" fill=\""
        << color << "\"/>"
        << "<text x=\"" << kPlotMargin + 20 + column << "\" y=\"" << legend_y << "\">" << xml_escape(e.name) << " (ATE "
        << fmt(e.ate.translation.rmse, 3) << " m)</text>\n";
    ++k;
  }
}

void draw_marker(std::ostream& svg, const PlotFrame& f, const SvgMarker& m) {
  const double x = f.px(m.position), y = f.py(m.position);
  if (m.triangle) {
    svg << "<polygon points=\"" << fmt(x, 1) << ',' << fmt(y - 7, 1) << ' ' << fmt(x - 6, 1) << ',' << fmt(y + 5, 1)
        << ' ' << fmt(x + 6, 1) << ',' << fmt(y + 5, 1) << "\" fill=\"" << m.color
        << "\" stroke=\"black\" stroke-width=\"0.8\"/>";
  } else {
    svg << "<circle cx=\"" << fmt(x, 1) << "\" cy=\"" << fmt(y, 1) << "\" r=\"5\" fill=\"white\" stroke=\"" << m.color
        << "\" stroke-width=\"2\"/>";
  }
  if (!m.label.empty()) {
    svg << "<text x=\"" << fmt(x + 8, 1) << "\" y=\"" << fmt(y - 6, 1) << "\" font-size=\"10\">" << xml_escape(m.label)
        << "</text>";
  }
  svg << "\n";
}

}  // namespace

std::string render_svg(const std::vector<Evaluation>& evaluations, const std::string& plane, const std::string& title,
                       const std::vector<SvgMarker>& markers, const std::string& marker_legend) {
  const PlotFrame frame(evaluations, plane);
  std::ostringstream svg;
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kPlotSize << "\" height=\"" << kPlotSize + 40
      << "\" font-family=\"sans-serif\" font-size=\"13\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      << "<text x=\"" << kPlotMargin << "\" y=\"30\" font-size=\"16\">" << xml_escape(title) << "</text>\n";
  draw_scale_bar(svg, frame);
  double legend_y = kPlotSize + 15;
  draw_estimates(svg, frame, evaluations, legend_y);
  for (const SvgMarker& m : markers) draw_marker(svg, frame, m);
  if (!marker_legend.empty()) {
    svg << "<text x=\"" << kPlotMargin << "\" y=\"50\" font-size=\"12\" fill=\"#333333\">" << xml_escape(marker_legend)
        << "</text>\n";
  }
  if (evaluations.size() > 3) legend_y += 18;  // a second row of estimates
  svg << "<text x=\"" << kPlotMargin << "\" y=\"" << legend_y + 18 << "\" fill=\"#555555\">- - ground truth</text>\n";
  svg << "</svg>\n";
  return svg.str();
}

}  // namespace cdc::eval
