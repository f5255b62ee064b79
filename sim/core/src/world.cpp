#include "cdc/sim/world.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>

namespace cdc::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Ray against a yawed box: slab test in the box frame.
bool hit_box(const Box& b, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t_out, Eigen::Vector3d& n_out) {
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  const Eigen::Vector3d p = o - b.center;
  const Eigen::Vector3d ol(c * p.x() + s * p.y(), -s * p.x() + c * p.y(), p.z());
  const Eigen::Vector3d dl(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  double t0 = -kInf, t1 = kInf;
  int axis = -1;
  double sign = 0;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(dl[i]) < 1e-12) {
      if (std::abs(ol[i]) > b.half[i]) {
        return false;
      }
      continue;
    }
    const double inv = 1.0 / dl[i];
    double ta = (-b.half[i] - ol[i]) * inv;
    double tb = (b.half[i] - ol[i]) * inv;
    double sa = -1.0;
    if (ta > tb) {
      std::swap(ta, tb);
      sa = 1.0;
    }
    if (ta > t0) {
      t0 = ta;
      axis = i;
      sign = sa;
    }
    t1 = std::min(t1, tb);
    if (t0 > t1) {
      return false;
    }
  }
  if (t0 <= 1e-9 || axis < 0) {
    return false;  // starts inside or behind
  }
  Eigen::Vector3d nl = Eigen::Vector3d::Zero();
  nl[axis] = sign;
  n_out = Eigen::Vector3d(c * nl.x() - s * nl.y(), s * nl.x() + c * nl.y(), nl.z());
  t_out = t0;
  return true;
}

bool hit_cylinder(const Cylinder& cy, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t_out,
                  Eigen::Vector3d& n_out) {
  const double px = o.x() - cy.x, py = o.y() - cy.y;
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a < 1e-12) {
    return false;
  }
  const double b = px * d.x() + py * d.y();
  const double c = px * px + py * py - cy.radius * cy.radius;
  const double disc = b * b - a * c;
  if (disc < 0 || c < 0) {
    return false;  // misses, or starts inside
  }
  const double t = (-b - std::sqrt(disc)) / a;
  if (t <= 1e-9) {
    return false;
  }
  const double z = o.z() + t * d.z();
  if (z < cy.z0 || z > cy.z1) {
    return false;
  }
  n_out = Eigen::Vector3d(px + t * d.x(), py + t * d.y(), 0) / cy.radius;
  t_out = t;
  return true;
}

double distance_to_box_2d(const Box& b, const Eigen::Vector2d& p) {
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  const Eigen::Vector2d q(p.x() - b.center.x(), p.y() - b.center.y());
  const Eigen::Vector2d l(c * q.x() + s * q.y(), -s * q.x() + c * q.y());
  const Eigen::Vector2d e(std::max(std::abs(l.x()) - b.half.x(), 0.0), std::max(std::abs(l.y()) - b.half.y(), 0.0));
  return e.norm();
}

}  // namespace

World::World(Ground ground, std::vector<Box> boxes, std::vector<Cylinder> cylinders, double cell_m)
    : ground_(ground), boxes_(std::move(boxes)), cylinders_(std::move(cylinders)), cell_(cell_m) {
  build_grid();
}

void World::build_grid() {
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  auto extend = [&](double x, double y, double r) {
    lo = lo.cwiseMin(Eigen::Vector2d(x - r, y - r));
    hi = hi.cwiseMax(Eigen::Vector2d(x + r, y + r));
  };
  for (const Box& b : boxes_) {
    extend(b.center.x(), b.center.y(), b.half.head<2>().norm());
  }
  for (const Cylinder& c : cylinders_) {
    extend(c.x, c.y, c.radius);
  }
  if (boxes_.empty() && cylinders_.empty()) {
    nx_ = ny_ = 0;
    return;
  }
  min_ = lo;
  nx_ = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / cell_)));
  ny_ = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / cell_)));
  cells_.assign(static_cast<size_t>(nx_) * static_cast<size_t>(ny_), {});
  auto add = [&](uint32_t id, double x, double y, double r) {
    const int i0 = std::clamp(static_cast<int>((x - r - min_.x()) / cell_), 0, nx_ - 1);
    const int i1 = std::clamp(static_cast<int>((x + r - min_.x()) / cell_), 0, nx_ - 1);
    const int j0 = std::clamp(static_cast<int>((y - r - min_.y()) / cell_), 0, ny_ - 1);
    const int j1 = std::clamp(static_cast<int>((y + r - min_.y()) / cell_), 0, ny_ - 1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        cells_[static_cast<size_t>(j) * static_cast<size_t>(nx_) + static_cast<size_t>(i)].push_back(id);
      }
    }
  };
  for (uint32_t k = 0; k < boxes_.size(); ++k) {
    add(k, boxes_[k].center.x(), boxes_[k].center.y(), boxes_[k].half.head<2>().norm());
  }
  for (uint32_t k = 0; k < cylinders_.size(); ++k) {
    add(static_cast<uint32_t>(boxes_.size()) + k, cylinders_[k].x, cylinders_[k].y, cylinders_[k].radius);
  }
}

std::optional<Hit> World::cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_range) const {
  Hit best;
  best.range = max_range;
  bool found = false;
  // Ground plane, analytic.
  const Eigen::Vector3d gn(-ground_.gx, -ground_.gy, 1.0);
  const double denom = gn.dot(d);
  if (std::abs(denom) > 1e-12) {
    const double t = (ground_.height(o.x(), o.y()) - o.z()) / (d.z() - ground_.gx * d.x() - ground_.gy * d.y());
    if (t > 1e-9 && t <= best.range) {
      best.range = t;
      best.normal = gn.normalized() * (denom < 0 ? 1.0 : -1.0);
      best.reflectance = ground_.reflectance;
      found = true;
    }
  }
  if (nx_ == 0) {
    return found ? std::optional<Hit>(best) : std::nullopt;
  }
  // 2D DDA over the grid (Amanatides & Woo), clipped to the grid's box.
  const Eigen::Vector2d o2 = o.head<2>(), d2 = d.head<2>();
  const Eigen::Vector2d hi = min_ + Eigen::Vector2d(nx_ * cell_, ny_ * cell_);
  double t_enter = 0, t_exit = best.range;
  for (int a = 0; a < 2; ++a) {
    if (std::abs(d2[a]) < 1e-12) {
      if (o2[a] < min_[a] || o2[a] > hi[a]) {
        return found ? std::optional<Hit>(best) : std::nullopt;
      }
      continue;
    }
    double ta = (min_[a] - o2[a]) / d2[a], tb = (hi[a] - o2[a]) / d2[a];
    if (ta > tb) std::swap(ta, tb);
    t_enter = std::max(t_enter, ta);
    t_exit = std::min(t_exit, tb);
  }
  if (t_enter > t_exit) {
    return found ? std::optional<Hit>(best) : std::nullopt;
  }
  const Eigen::Vector2d p = o2 + d2 * (t_enter + 1e-9);
  int i = std::clamp(static_cast<int>((p.x() - min_.x()) / cell_), 0, nx_ - 1);
  int j = std::clamp(static_cast<int>((p.y() - min_.y()) / cell_), 0, ny_ - 1);
  const int si = d2.x() > 0 ? 1 : -1, sj = d2.y() > 0 ? 1 : -1;
  auto boundary = [&](int idx, int step, int axis) {
    return min_[axis] + (idx + (step > 0 ? 1 : 0)) * cell_;
  };
  double tx = std::abs(d2.x()) > 1e-12 ? (boundary(i, si, 0) - o2.x()) / d2.x() : kInf;
  double ty = std::abs(d2.y()) > 1e-12 ? (boundary(j, sj, 1) - o2.y()) / d2.y() : kInf;
  const double dtx = std::abs(d2.x()) > 1e-12 ? cell_ / std::abs(d2.x()) : kInf;
  const double dty = std::abs(d2.y()) > 1e-12 ? cell_ / std::abs(d2.y()) : kInf;
  while (true) {
    const auto& cell = cells_[static_cast<size_t>(j) * static_cast<size_t>(nx_) + static_cast<size_t>(i)];
    for (uint32_t id : cell) {
      double t = 0;
      Eigen::Vector3d n;
      if (id < boxes_.size()) {
        if (hit_box(boxes_[id], o, d, t, n) && t < best.range) {
          best = Hit{t, n, boxes_[id].reflectance};
          found = true;
        }
      } else {
        const Cylinder& cy = cylinders_[id - boxes_.size()];
        if (hit_cylinder(cy, o, d, t, n) && t < best.range) {
          best = Hit{t, n, cy.reflectance};
          found = true;
        }
      }
    }
    const double t_next = std::min(tx, ty);
    if (t_next >= best.range || t_next > t_exit) {
      break;  // nothing farther can be nearer than what was hit
    }
    if (tx < ty) {
      i += si;
      tx += dtx;
      if (i < 0 || i >= nx_) break;
    } else {
      j += sj;
      ty += dty;
      if (j < 0 || j >= ny_) break;
    }
  }
  return found ? std::optional<Hit>(best) : std::nullopt;
}

World World::generate(const std::vector<std::vector<Eigen::Vector3d>>& paths, const WorldOptions& opt) {
  std::mt19937_64 rng(opt.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto uni = [&](double a, double b) { return a + (b - a) * u(rng); };
  std::vector<Eigen::Vector2d> samples;  // every path point, for clearance checks
  for (const auto& path : paths) {
    for (const auto& p : path) {
      samples.push_back(p.head<2>());
    }
  }
  Ground ground;
  ground.gx = uni(-opt.max_slope, opt.max_slope);
  ground.gy = uni(-opt.max_slope, opt.max_slope);
  if (!paths.empty() && !paths.front().empty()) {
    const Eigen::Vector3d& s = paths.front().front();
    ground.z0 = s.z() - 1.7 - ground.gx * s.x() - ground.gy * s.y();  // sensor about 1.7 m above ground at the start
  }
  std::vector<Box> boxes;
  std::vector<Cylinder> cylinders;
  // A coarse occupancy of path points, so that clearance checks look only nearby.
  const double cell = 20.0;
  std::unordered_map<int64_t, std::vector<Eigen::Vector2d>> near;
  auto key = [&](double x, double y) {
    return (static_cast<int64_t>(std::floor(x / cell)) << 32) ^ static_cast<int64_t>(static_cast<uint32_t>(std::floor(y / cell)));
  };
  for (const auto& s : samples) {
    near[key(s.x(), s.y())].push_back(s);
  }
  auto clear_of_paths = [&](const Box& b) {
    const double r = b.half.head<2>().norm() + opt.clearance_m;
    for (double dx = -r; dx <= r + cell; dx += cell) {
      for (double dy = -r; dy <= r + cell; dy += cell) {
        auto it = near.find(key(b.center.x() + dx, b.center.y() + dy));
        if (it == near.end()) continue;
        for (const auto& s : it->second) {
          if (distance_to_box_2d(b, s) < opt.clearance_m) return false;
        }
      }
    }
    return true;
  };
  auto ground_at = [&](double x, double y) { return ground.height(x, y); };
  for (const auto& path : paths) {
    double since = opt.spacing_m;
    for (size_t k = 1; k < path.size(); ++k) {
      since += (path[k] - path[k - 1]).head<2>().norm();
      if (since < opt.spacing_m) continue;
      since = 0;
      const Eigen::Vector2d dir = (path[k] - path[k - 1]).head<2>().normalized();
      const Eigen::Vector2d left(-dir.y(), dir.x());
      const double heading = std::atan2(dir.y(), dir.x());
      for (double side : {-1.0, 1.0}) {
        const Eigen::Vector2d base = path[k].head<2>();
        // A building set back from the road.
        {
          Box b;
          const double depth = uni(6, 18), width = uni(8, 25), height = uni(6, 30);
          const Eigen::Vector2d c = base + side * left * (uni(9, 14) + depth);
          b.center = Eigen::Vector3d(c.x(), c.y(), ground_at(c.x(), c.y()) + height / 2);
          b.half = Eigen::Vector3d(width / 2, depth, height / 2);
          b.yaw = heading + uni(-0.15, 0.15);
          b.reflectance = static_cast<float>(uni(0.3, 0.8));
          if (clear_of_paths(b)) boxes.push_back(b);
        }
        const double r = u(rng);
        const Eigen::Vector2d c = base + side * left * uni(4.0, 7.0) + dir * uni(-5, 5);
        if (r < 0.35) {  // a pole
          Cylinder p{c.x(), c.y(), uni(0.08, 0.2), ground_at(c.x(), c.y()), ground_at(c.x(), c.y()) + uni(3, 8),
                     static_cast<float>(uni(0.4, 0.9))};
          Box probe{Eigen::Vector3d(p.x, p.y, 0), Eigen::Vector3d(p.radius, p.radius, 1), 0, 0};
          if (clear_of_paths(probe)) cylinders.push_back(p);
        } else if (r < 0.65) {  // a tree: trunk and crown
          const double h = uni(4, 9);
          Cylinder t{c.x(), c.y(), uni(0.15, 0.35), ground_at(c.x(), c.y()), ground_at(c.x(), c.y()) + h * 0.6, 0.35f};
          Box crown{Eigen::Vector3d(c.x(), c.y(), ground_at(c.x(), c.y()) + h * 0.75), Eigen::Vector3d::Constant(uni(1.2, 2.2)),
                    uni(0, 3.14), 0.25f};
          crown.half.z() = h * 0.2;
          if (clear_of_paths(crown)) {
            cylinders.push_back(t);
            boxes.push_back(crown);
          }
        } else if (r < 0.9) {  // a parked car along the road
          Box car{Eigen::Vector3d(c.x(), c.y(), ground_at(c.x(), c.y()) + 0.75), Eigen::Vector3d(2.2, 0.9, 0.75),
                  heading + uni(-0.05, 0.05), static_cast<float>(uni(0.5, 0.9))};
          if (clear_of_paths(car)) boxes.push_back(car);
        } else {  // a wall segment or clutter
          Box w{Eigen::Vector3d(c.x(), c.y(), ground_at(c.x(), c.y()) + 1.0), Eigen::Vector3d(uni(0.3, 4), uni(0.2, 0.6), uni(0.4, 1.5)),
                heading + uni(-0.5, 0.5), static_cast<float>(uni(0.2, 0.7))};
          if (clear_of_paths(w)) boxes.push_back(w);
        }
      }
    }
  }
  return World(ground, std::move(boxes), std::move(cylinders), opt.cell_m);
}

}  // namespace cdc::sim
