#pragma once

// Scenes of axis-aligned rectangles (floors, walls, box faces) with exact
// ray casting, for testing depth association against known geometry.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace ag::test {

/// A rectangle in the plane x[axis] = value, spanning [lo, hi] in the two
/// other axes ((axis + 1) % 3, (axis + 2) % 3).
struct Rect {
  int axis = 2;
  double value = 0.0;
  Eigen::Vector2d lo = Eigen::Vector2d::Zero();
  Eigen::Vector2d hi = Eigen::Vector2d::Zero();

  double Area() const { return (hi - lo).prod(); }
  Eigen::Vector3d Normal() const { return Eigen::Vector3d::Unit(axis); }
};

class Scene {
 public:
  void AddRect(int axis, double value, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
    rects_.push_back(Rect{axis, value, lo, hi});
  }

  /// The five visible faces (no bottom) of the box [lo, hi].
  void AddBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    for (int axis = 0; axis < 3; ++axis) {
      const int a1 = (axis + 1) % 3;
      const int a2 = (axis + 2) % 3;
      const Eigen::Vector2d rlo(lo[a1], lo[a2]);
      const Eigen::Vector2d rhi(hi[a1], hi[a2]);
      if (axis != 2) AddRect(axis, lo[axis], rlo, rhi);
      AddRect(axis, hi[axis], rlo, rhi);
    }
  }

  const std::vector<Rect>& rects() const { return rects_; }

  /// First intersection of o + t d with t in (t_min, t_max]; false if none.
  bool Cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min, double t_max,
            double* t_hit, int* rect_hit) const {
    double best = std::numeric_limits<double>::infinity();
    int which = -1;
    for (size_t i = 0; i < rects_.size(); ++i) {
      const Rect& r = rects_[i];
      if (d[r.axis] == 0.0) continue;
      const double t = (r.value - o[r.axis]) / d[r.axis];
      if (!(t > t_min && t <= t_max && t < best)) continue;
      const Eigen::Vector3d p = o + t * d;
      const double u = p[(r.axis + 1) % 3];
      const double v = p[(r.axis + 2) % 3];
      if (u >= r.lo.x() && u <= r.hi.x() && v >= r.lo.y() && v <= r.hi.y()) {
        best = t;
        which = static_cast<int>(i);
      }
    }
    if (which < 0) return false;
    *t_hit = best;
    *rect_hit = which;
    return true;
  }

  /// Uniform random points on every rectangle, `density` per square metre,
  /// in random order (so per-voxel caps keep a random subset).
  std::vector<Eigen::Vector3f> Sample(double density, std::mt19937* rng) const {
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<Eigen::Vector3f> points;
    for (const Rect& r : rects_) {
      const int n = static_cast<int>(std::lround(r.Area() * density));
      for (int i = 0; i < n; ++i) {
        Eigen::Vector3d p;
        p[r.axis] = r.value;
        p[(r.axis + 1) % 3] = r.lo.x() + (r.hi.x() - r.lo.x()) * unit(*rng);
        p[(r.axis + 2) % 3] = r.lo.y() + (r.hi.y() - r.lo.y()) * unit(*rng);
        points.push_back(p.cast<float>());
      }
    }
    std::shuffle(points.begin(), points.end(), *rng);
    return points;
  }

 private:
  std::vector<Rect> rects_;
};

}  // namespace ag::test
