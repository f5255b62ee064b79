#include "cdc/sim/world.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
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

// Moller-Trumbore ray/triangle intersection; normal faces the ray.
bool hit_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                  const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t_out, Eigen::Vector3d& n_out) {
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d pv = d.cross(e2);
  const double det = e1.dot(pv);
  if (std::abs(det) < 1e-12) return false;
  const double inv = 1.0 / det;
  const Eigen::Vector3d tv = o - a;
  const double u = tv.dot(pv) * inv;
  if (u < 0 || u > 1) return false;
  const Eigen::Vector3d qv = tv.cross(e1);
  const double v = d.dot(qv) * inv;
  if (v < 0 || u + v > 1) return false;
  const double t = e2.dot(qv) * inv;
  if (t <= 1e-9) return false;
  Eigen::Vector3d n = e1.cross(e2).normalized();
  if (n.dot(d) > 0) n = -n;
  t_out = t;
  n_out = n;
  return true;
}

}  // namespace

double Terrain::height(double x, double y) const {
  if (empty()) return 0;
  const double fx = std::clamp((x - origin.x()) / cell, 0.0, static_cast<double>(nx));
  const double fy = std::clamp((y - origin.y()) / cell, 0.0, static_cast<double>(ny));
  const int i = std::min(static_cast<int>(fx), nx - 1), j = std::min(static_cast<int>(fy), ny - 1);
  const double u = fx - i, v = fy - j;
  if (u + v <= 1) {
    return vertex(i, j) + u * (vertex(i + 1, j) - vertex(i, j)) + v * (vertex(i, j + 1) - vertex(i, j));
  }
  return vertex(i + 1, j + 1) + (1 - u) * (vertex(i, j + 1) - vertex(i + 1, j + 1)) +
         (1 - v) * (vertex(i + 1, j) - vertex(i + 1, j + 1));
}

double World::ground_height(double x, double y) const {
  return terrain_.empty() ? ground_.height(x, y) : terrain_.height(x, y);
}

bool World::hit_terrain_cell(int i, int j, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t,
                             Eigen::Vector3d& n) const {
  const double x0 = terrain_.origin.x() + i * terrain_.cell, y0 = terrain_.origin.y() + j * terrain_.cell;
  const double x1 = x0 + terrain_.cell, y1 = y0 + terrain_.cell;
  const Eigen::Vector3d p00(x0, y0, terrain_.vertex(i, j)), p10(x1, y0, terrain_.vertex(i + 1, j));
  const Eigen::Vector3d p01(x0, y1, terrain_.vertex(i, j + 1)), p11(x1, y1, terrain_.vertex(i + 1, j + 1));
  double ta = 0, tb = 0;
  Eigen::Vector3d na, nb;
  const bool a = hit_triangle(p00, p10, p01, o, d, ta, na);
  const bool b = hit_triangle(p10, p11, p01, o, d, tb, nb);
  if (!a && !b) return false;
  if (a && (!b || ta <= tb)) {
    t = ta;
    n = na;
  } else {
    t = tb;
    n = nb;
  }
  return true;
}

World::World(Terrain terrain, std::vector<Box> boxes, std::vector<Cylinder> cylinders)
    : terrain_(std::move(terrain)), boxes_(std::move(boxes)), cylinders_(std::move(cylinders)) {
  if (terrain_.empty() ||
      terrain_.z.size() != static_cast<size_t>(terrain_.nx + 1) * static_cast<size_t>(terrain_.ny + 1)) {
    throw std::invalid_argument("World: terrain needs nx, ny > 0 and (nx + 1) * (ny + 1) heights");
  }
  cell_ = terrain_.cell;
  min_ = terrain_.origin;
  nx_ = terrain_.nx;
  ny_ = terrain_.ny;
  index_objects();
}

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
  index_objects();
}

void World::index_objects() {
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
  // Ground plane, analytic (a terrain is hit cell by cell below).
  const Eigen::Vector3d gn(-ground_.gx, -ground_.gy, 1.0);
  const double denom = gn.dot(d);
  if (terrain_.empty() && std::abs(denom) > 1e-12) {
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
  auto boundary = [&](int idx, int step, int axis) { return min_[axis] + (idx + (step > 0 ? 1 : 0)) * cell_; };
  double tx = std::abs(d2.x()) > 1e-12 ? (boundary(i, si, 0) - o2.x()) / d2.x() : kInf;
  double ty = std::abs(d2.y()) > 1e-12 ? (boundary(j, sj, 1) - o2.y()) / d2.y() : kInf;
  const double dtx = std::abs(d2.x()) > 1e-12 ? cell_ / std::abs(d2.x()) : kInf;
  const double dty = std::abs(d2.y()) > 1e-12 ? cell_ / std::abs(d2.y()) : kInf;
  while (true) {
    const auto& cell = cells_[static_cast<size_t>(j) * static_cast<size_t>(nx_) + static_cast<size_t>(i)];
    if (!terrain_.empty()) {
      double t = 0;
      Eigen::Vector3d n;
      if (hit_terrain_cell(i, j, o, d, t, n) && t < best.range) {
        best = Hit{t, n, ground_.reflectance};
        found = true;
      }
    }
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

namespace {

// Terrain under the paths: every vertex takes the mean height (minus the sensor height) of the
// path points nearest to it; vertices with none take their nearest seeded neighbour's value
// (breadth-first), then are smoothed so that the ground away from the roads has no terraces.
// Where passes over the same place disagree in height by more than kMaxPassSpread (an underpass,
// or a ground truth that does not close in elevation: KITTI 09 ends 3.1 m below its start), the
// vertex takes the lowest: a mean would lift the ground into the lower pass's sensor, while the
// higher pass merely drives above a lower ground, as over a bridge.
Terrain make_terrain(const std::vector<std::vector<Eigen::Vector3d>>& paths, const WorldOptions& opt) {
  Terrain t;
  t.cell = opt.cell_m;
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  for (const auto& path : paths) {
    for (const auto& p : path) {
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
  }
  if (!std::isfinite(lo.x())) {
    lo = hi = Eigen::Vector2d::Zero();
  }
  t.origin = lo - Eigen::Vector2d::Constant(opt.terrain_margin_m);
  t.nx = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x() + 2 * opt.terrain_margin_m) / t.cell)));
  t.ny = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y() + 2 * opt.terrain_margin_m) / t.cell)));
  const int w = t.nx + 1, h = t.ny + 1;
  const size_t n = static_cast<size_t>(w) * static_cast<size_t>(h);
  constexpr double kMaxPassSpread = 1.0;  // [m]
  std::vector<double> sum(n, 0.0), lowest(n, kInf), highest(n, -kInf);
  std::vector<int> count(n, 0);
  for (const auto& path : paths) {
    for (const auto& p : path) {
      const int i = std::clamp(static_cast<int>(std::lround((p.x() - t.origin.x()) / t.cell)), 0, t.nx);
      const int j = std::clamp(static_cast<int>(std::lround((p.y() - t.origin.y()) / t.cell)), 0, t.ny);
      const size_t k = static_cast<size_t>(j) * static_cast<size_t>(w) + static_cast<size_t>(i);
      const double g = p.z() - opt.sensor_height_m;
      sum[k] += g;
      lowest[k] = std::min(lowest[k], g);
      highest[k] = std::max(highest[k], g);
      ++count[k];
    }
  }
  t.z.assign(n, 0.0);
  std::vector<char> seeded(n, 0), known(n, 0);
  std::vector<size_t> frontier;
  for (size_t k = 0; k < n; ++k) {
    if (count[k] > 0) {
      t.z[k] = highest[k] - lowest[k] > kMaxPassSpread ? lowest[k] : sum[k] / count[k];
      seeded[k] = known[k] = 1;
      frontier.push_back(k);
    }
  }
  if (frontier.empty()) {
    return t;  // flat at zero
  }
  while (!frontier.empty()) {
    std::vector<size_t> next;
    for (size_t k : frontier) {
      const int i = static_cast<int>(k % static_cast<size_t>(w)), j = static_cast<int>(k / static_cast<size_t>(w));
      const int di[4] = {1, -1, 0, 0}, dj[4] = {0, 0, 1, -1};
      for (int m = 0; m < 4; ++m) {
        const int a = i + di[m], b = j + dj[m];
        if (a < 0 || a > t.nx || b < 0 || b > t.ny) continue;
        const size_t q = static_cast<size_t>(b) * static_cast<size_t>(w) + static_cast<size_t>(a);
        if (!known[q]) {
          known[q] = 1;
          t.z[q] = t.z[k];
          next.push_back(q);
        }
      }
    }
    frontier.swap(next);
  }
  for (int iter = 0; iter < 10; ++iter) {
    std::vector<double> z = t.z;
    for (int j = 0; j <= t.ny; ++j) {
      for (int i = 0; i <= t.nx; ++i) {
        const size_t k = static_cast<size_t>(j) * static_cast<size_t>(w) + static_cast<size_t>(i);
        if (seeded[k]) continue;
        double s = 0;
        int c = 0;
        for (int b = std::max(0, j - 1); b <= std::min(t.ny, j + 1); ++b) {
          for (int a = std::max(0, i - 1); a <= std::min(t.nx, i + 1); ++a) {
            s += t.z[static_cast<size_t>(b) * static_cast<size_t>(w) + static_cast<size_t>(a)];
            ++c;
          }
        }
        z[k] = s / c;
      }
    }
    t.z.swap(z);
  }
  return t;
}

}  // namespace

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
  const Terrain terrain = make_terrain(paths, opt);
  std::vector<Box> boxes;
  std::vector<Cylinder> cylinders;
  // A coarse occupancy of path points, so that clearance checks look only nearby.
  const double cell = 20.0;
  std::unordered_map<int64_t, std::vector<Eigen::Vector2d>> near;
  auto key = [&](double x, double y) {
    return (static_cast<int64_t>(std::floor(x / cell)) << 32) ^
           static_cast<int64_t>(static_cast<uint32_t>(std::floor(y / cell)));
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
  auto ground_at = [&](double x, double y) { return terrain.height(x, y); };
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
          Cylinder p{c.x(),
                     c.y(),
                     uni(0.08, 0.2),
                     ground_at(c.x(), c.y()),
                     ground_at(c.x(), c.y()) + uni(3, 8),
                     static_cast<float>(uni(0.4, 0.9))};
          Box probe{Eigen::Vector3d(p.x, p.y, 0), Eigen::Vector3d(p.radius, p.radius, 1), 0, 0};
          if (clear_of_paths(probe)) cylinders.push_back(p);
        } else if (r < 0.65) {  // a tree: trunk and crown
          const double h = uni(4, 9);
          Cylinder t{c.x(), c.y(), uni(0.15, 0.35), ground_at(c.x(), c.y()), ground_at(c.x(), c.y()) + h * 0.6, 0.35f};
          Box crown{Eigen::Vector3d(c.x(), c.y(), ground_at(c.x(), c.y()) + h * 0.75),
                    Eigen::Vector3d::Constant(uni(1.2, 2.2)), uni(0, 3.14), 0.25f};
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
          Box w{Eigen::Vector3d(c.x(), c.y(), ground_at(c.x(), c.y()) + 1.0),
                Eigen::Vector3d(uni(0.3, 4), uni(0.2, 0.6), uni(0.4, 1.5)), heading + uni(-0.5, 0.5),
                static_cast<float>(uni(0.2, 0.7))};
          if (clear_of_paths(w)) boxes.push_back(w);
        }
      }
    }
  }
  return World(terrain, std::move(boxes), std::move(cylinders));
}

}  // namespace cdc::sim
