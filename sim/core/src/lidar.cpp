#include "cdc/sim/lidar.hpp"

#include <stdexcept>
#include <string>

#include <cmath>

namespace cdc::sim {

LidarModel LidarModel::vlp16() {
  LidarModel m;
  m.name = "vlp16";
  for (int i = 0; i < 16; ++i) {
    m.elevations_deg.push_back(-15.0 + 2.0 * i);
  }
  m.columns = 1800;
  m.max_range_m = 100.0;
  m.range_sigma_m = 0.03;
  m.dropout = 0.01;
  return m;
}

LidarModel LidarModel::hdl64() {
  LidarModel m;
  m.name = "hdl64";
  for (int i = 0; i < 64; ++i) {
    m.elevations_deg.push_back(-24.9 + 26.9 * i / 63.0);
  }
  m.columns = 2083;
  m.max_range_m = 120.0;
  m.range_sigma_m = 0.02;
  m.dropout = 0.01;
  return m;
}

std::vector<LidarReturn> sweep(const World& world, const LidarModel& model,
                               const std::function<Eigen::Isometry3d(double)>& pose_at, std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, model.range_sigma_m);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const size_t beams = model.elevations_deg.size();
  auto check = [beams](const std::vector<double>& v, const char* what) {
    if (!v.empty() && v.size() != beams) {
      throw std::invalid_argument(std::string("LidarModel: ") + what + " has " + std::to_string(v.size()) +
                                  " entries for " + std::to_string(beams) + " beams");
    }
  };
  check(model.elevation_error_deg, "elevation_error_deg");
  check(model.azimuth_error_deg, "azimuth_error_deg");
  check(model.range_offset_m, "range_offset_m");
  std::vector<double> ce(beams), se(beams), ce_true(beams), se_true(beams), ca_err(beams, 1.0), sa_err(beams, 0.0);
  for (size_t b = 0; b < beams; ++b) {
    const double e = model.elevations_deg[b] * M_PI / 180.0;
    ce[b] = std::cos(e);
    se[b] = std::sin(e);
    const double et = e + (model.elevation_error_deg.empty() ? 0.0 : model.elevation_error_deg[b] * M_PI / 180.0);
    ce_true[b] = std::cos(et);
    se_true[b] = std::sin(et);
    if (!model.azimuth_error_deg.empty()) {
      ca_err[b] = std::cos(model.azimuth_error_deg[b] * M_PI / 180.0);
      sa_err[b] = std::sin(model.azimuth_error_deg[b] * M_PI / 180.0);
    }
  }
  std::vector<LidarReturn> out;
  out.reserve(model.rays());
  const double period = model.period_s();
  for (int c = 0; c < model.columns; ++c) {
    const double t = period * c / model.columns;
    const double az = 2.0 * M_PI * c / model.columns;
    const double ca = std::cos(az), sa = std::sin(az);
    const Eigen::Isometry3d T = pose_at(t);
    const Eigen::Matrix3d R = T.rotation();
    const Eigen::Vector3d o = T.translation();
    for (size_t b = 0; b < beams; ++b) {
      const Eigen::Vector3d d_sensor(ce[b] * ca, ce[b] * sa, se[b]);  // as reported
      // As fired: the true elevation, and the column's azimuth turned by the beam's azimuth error.
      const double ca_true = ca * ca_err[b] - sa * sa_err[b], sa_true = sa * ca_err[b] + ca * sa_err[b];
      const Eigen::Vector3d d = R * Eigen::Vector3d(ce_true[b] * ca_true, ce_true[b] * sa_true, se_true[b]);
      const auto hit = world.cast(o, d, model.max_range_m);
      if (!hit) {
        continue;
      }
      if (model.dropout > 0 && u(rng) < model.dropout) {
        continue;
      }
      const double range = hit->range + (model.range_offset_m.empty() ? 0.0 : model.range_offset_m[b]) +
                           (model.range_sigma_m > 0 ? noise(rng) : 0.0);
      if (range < model.min_range_m || range > model.max_range_m) {
        continue;
      }
      const Eigen::Vector3d p = d_sensor * range;
      const double incidence = std::abs(hit->normal.dot(d));
      out.push_back(LidarReturn{static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()),
                                static_cast<float>(hit->reflectance * incidence), static_cast<float>(t),
                                static_cast<uint16_t>(b)});
    }
  }
  return out;
}

}  // namespace cdc::sim
