#include "tools/sim/trajectory.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "tools/sim/random.h"

namespace ag {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kDeg = M_PI / 180.0;
constexpr double kGravity = 9.81;

}  // namespace

void PathOptions::Check() const {
  CheckOption(shape == "waypoints" || shape == "orbit" || shape == "lawnmower", "shape",
              "must be waypoints, orbit or lawnmower, got '" + shape + "'");
  if (shape == "waypoints") {
    CheckOption(waypoints.size() >= 4 && waypoints.size() % 2 == 0, "waypoints",
                "needs at least two x, y pairs");
  }
  CheckOption(center.size() == 2, "center", "must be [x, y]");
  CheckOption(radius_m > 0.5, "radius_m", "must be > 0.5");
  CheckOption(area.size() == 4 && area[2] > area[0] && area[3] > area[1], "area",
              "must be [xmin, ymin, xmax, ymax] with max > min");
  CheckOption(spacing_m > 0.5, "spacing_m", "must be > 0.5");
  CheckOption(speed_mps > 0 && speed_mps < 30, "speed_mps", "must be in (0, 30)");
  CheckOption(accel_time_s >= 0, "accel_time_s", "must be >= 0");
  CheckOption(start_offset_m >= 0, "start_offset_m", "must be >= 0");
  CheckOption(heading == "tangent" || heading == "look_at" || heading == "fixed", "heading",
              "must be tangent, look_at or fixed, got '" + heading + "'");
  CheckOption(look_at.size() == 2, "look_at", "must be [x, y]");
}

std::vector<Vector2d> PathWaypoints(const PathOptions& o) {
  std::vector<Vector2d> pts;
  if (o.shape == "orbit") {
    const int n = 16;
    for (int i = 0; i < n; ++i) {
      const double a = (o.clockwise ? -1.0 : 1.0) * 2.0 * M_PI * i / n;
      pts.emplace_back(o.center[0] + o.radius_m * std::cos(a),
                       o.center[1] + o.radius_m * std::sin(a));
    }
  } else if (o.shape == "lawnmower") {
    // Rows along x, with intermediate points so the spline stays straight
    // along the rows and turns only at the ends.
    const double x0 = o.area[0], y0 = o.area[1], x1 = o.area[2], y1 = o.area[3];
    const int rows = std::max(2, static_cast<int>(std::floor((y1 - y0) / o.spacing_m)) + 1);
    const int per_row = std::max(2, static_cast<int>(std::ceil((x1 - x0) / o.spacing_m)) + 1);
    for (int r = 0; r < rows; ++r) {
      const double y = y0 + r * (y1 - y0) / (rows - 1);
      for (int k = 0; k < per_row; ++k) {
        const double f = static_cast<double>(k) / (per_row - 1);
        const double x = (r % 2 == 0) ? x0 + f * (x1 - x0) : x1 - f * (x1 - x0);
        pts.emplace_back(x, y);
      }
    }
  } else {
    for (size_t i = 0; i + 1 < o.waypoints.size(); i += 2)
      pts.emplace_back(o.waypoints[i], o.waypoints[i + 1]);
    if (o.clockwise) std::reverse(pts.begin(), pts.end());
  }
  return pts;
}

SplinePath::SplinePath(std::vector<Vector2d> points, bool closed)
    : points_(std::move(points)), closed_(closed) {
  if (points_.size() < 2) throw OptionError("waypoints", "a path needs at least two points");
  segments_ = static_cast<int>(closed_ ? points_.size() : points_.size() - 1);
  cumulative_.assign(1, 0.0);
  Vector2d prev = Evaluate(0, 0.0);
  for (int seg = 0; seg < segments_; ++seg) {
    for (int k = 1; k <= kSamplesPerSegment; ++k) {
      const Vector2d p = Evaluate(seg, static_cast<double>(k) / kSamplesPerSegment);
      cumulative_.push_back(cumulative_.back() + (p - prev).norm());
      prev = p;
    }
  }
}

Vector2d SplinePath::Evaluate(int segment, double u) const {
  const int n = static_cast<int>(points_.size());
  auto point = [&](int i) -> Vector2d {
    if (closed_) return points_[static_cast<size_t>(((i % n) + n) % n)];
    if (i < 0) return 2.0 * points_[0] - points_[1];
    if (i >= n) return 2.0 * points_[n - 1] - points_[n - 2];
    return points_[static_cast<size_t>(i)];
  };
  const Vector2d p0 = point(segment - 1), p1 = point(segment), p2 = point(segment + 1),
                 p3 = point(segment + 2);
  // Centripetal parameterisation (alpha = 0.5): no cusps or self-intersections.
  auto knot = [](const Vector2d& a, const Vector2d& b, double t) {
    return t + std::max(std::sqrt((b - a).norm()), 1e-6);
  };
  const double t0 = 0.0, t1 = knot(p0, p1, t0), t2 = knot(p1, p2, t1), t3 = knot(p2, p3, t2);
  const double t = t1 + u * (t2 - t1);
  const Vector2d a1 = (t1 - t) / (t1 - t0) * p0 + (t - t0) / (t1 - t0) * p1;
  const Vector2d a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2;
  const Vector2d a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3;
  const Vector2d b1 = (t2 - t) / (t2 - t0) * a1 + (t - t0) / (t2 - t0) * a2;
  const Vector2d b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3;
  return (t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2;
}

Vector2d SplinePath::Position(double s) const {
  const double len = length();
  if (closed_) {
    s = std::fmod(s, len);
    if (s < 0) s += len;
  } else {
    s = std::clamp(s, 0.0, len);
  }
  const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), s);
  const auto k = static_cast<int>(std::clamp<std::ptrdiff_t>(
      it - cumulative_.begin() - 1, 0, static_cast<std::ptrdiff_t>(cumulative_.size()) - 2));
  const double span = cumulative_[k + 1] - cumulative_[k];
  const double f = span > 0 ? (s - cumulative_[k]) / span : 0.0;
  const int segment = std::min(k / kSamplesPerSegment, segments_ - 1);
  const double u = (k - segment * kSamplesPerSegment + f) / kSamplesPerSegment;
  return Evaluate(segment, std::clamp(u, 0.0, 1.0));
}

std::vector<Vector2d> SplinePath::Sample(double step_m) const {
  std::vector<Vector2d> out;
  for (double s = 0.0; s < length(); s += step_m) out.push_back(Position(s));
  out.push_back(Position(length()));
  return out;
}

AgentMotion::AgentMotion(const PathOptions& path, bool air, double height_m,
                         double altitude_variation_m, double vibration_deg, uint64_t seed)
    : options_(path),
      spline_(PathWaypoints(path),
              path.shape == "orbit" ? true : (path.shape == "lawnmower" ? false : path.closed)),
      air_(air),
      height_m_(height_m),
      altitude_variation_m_(altitude_variation_m),
      vibration_rad_(vibration_deg * kDeg) {
  SimRandom rng(seed, "vibration");
  for (int i = 0; i < 9; ++i) {
    phases_[i] = rng.Uniform(0.0, 2.0 * M_PI);
    freqs_[i] = air ? rng.Uniform(0.3, 1.5) : rng.Uniform(0.8, 4.0);
  }
}

double AgentMotion::ArcLength(double tau) const {
  const double v = options_.speed_mps;
  const double ta = options_.accel_time_s;
  double s;
  if (tau <= 0.0) {
    s = 0.0;
  } else if (tau < ta) {
    s = 0.5 * v * tau * tau / ta;  // constant acceleration from rest
  } else {
    s = v * (tau - 0.5 * ta);
  }
  s += options_.start_offset_m;
  if (!spline_.closed()) {
    // An open path ends with the mirror of the start: constant deceleration
    // to rest at its end, so velocity (and a UAV's tilt) stay continuous.
    const double brake_start = spline_.length() - 0.5 * v * ta;
    if (s > brake_start) {
      const double t_brake = (s - brake_start) / v;  // time since braking began
      s = t_brake >= ta ? spline_.length()
                        : brake_start + v * t_brake - 0.5 * v * t_brake * t_brake / ta;
    }
  }
  return s;
}

Vector3d AgentMotion::Position(double tau) const {
  const Vector2d xy = spline_.Position(ArcLength(tau));
  double z = height_m_;
  if (air_) {
    z += altitude_variation_m_ * std::sin(2.0 * M_PI * tau / 23.0 + phases_[8]);
  } else {
    // Suspension bob of a few millimetres.
    z += 0.1 * vibration_rad_ *
         (std::sin(2.0 * M_PI * freqs_[6] * tau + phases_[6]) +
          std::sin(2.0 * M_PI * freqs_[7] * tau + phases_[7]));
  }
  return Vector3d(xy.x(), xy.y(), z);
}

double AgentMotion::Yaw(double tau) const {
  const double offset = options_.yaw_deg * kDeg;
  if (options_.heading == "fixed") return offset;
  if (options_.heading == "look_at") {
    const Vector3d p = Position(tau);
    return std::atan2(options_.look_at[1] - p.y(), options_.look_at[0] - p.x()) + offset;
  }
  // Tangent by a central difference in arc length (the spline is C1).
  const double s = ArcLength(tau);
  const double h = 0.05;
  double s0 = s - h, s1 = s + h;
  if (!spline_.closed()) {
    s0 = std::clamp(s0, 0.0, spline_.length() - 2 * h);
    s1 = s0 + 2 * h;
  }
  const Vector2d d = spline_.Position(s1) - spline_.Position(s0);
  return std::atan2(d.y(), d.x()) + offset;
}

Pose AgentMotion::BodyPose(double tau) const {
  const Vector3d p = Position(tau);
  const double yaw = Yaw(tau);
  auto wobble = [&](int i) {
    return vibration_rad_ *
           (std::sin(2.0 * M_PI * freqs_[i] * tau + phases_[i]) +
            0.5 * std::sin(2.0 * M_PI * freqs_[i + 1] * 2.3 * tau + phases_[i + 1])) /
           1.5;
  };
  Eigen::Matrix3d R;
  if (air_) {
    // Quadrotor: thrust along body z balances gravity plus acceleration.
    const double h = 0.05;
    const Vector3d a = (Position(tau + h) - 2.0 * p + Position(tau - h)) / (h * h);
    const Vector3d b3 = (a + Vector3d(0, 0, kGravity)).normalized();
    const Vector3d b1c(std::cos(yaw), std::sin(yaw), 0.0);
    const Vector3d b2 = b3.cross(b1c).normalized();
    const Vector3d b1 = b2.cross(b3);
    R.col(0) = b1;
    R.col(1) = b2;
    R.col(2) = b3;
  } else {
    R = RotZ(yaw);
  }
  R = R * Eigen::AngleAxisd(wobble(2), Vector3d::UnitY()).toRotationMatrix() *
      Eigen::AngleAxisd(wobble(0), Vector3d::UnitX()).toRotationMatrix();
  Pose T = Pose::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

}  // namespace ag
