#pragma once

// Smooth agent motion in the scene frame W: a centripetal Catmull-Rom spline
// through waypoints, travelled at constant speed after a smooth start. The
// UGV keeps its wheels on the plane (heading = path tangent, small
// vibration); a UAV tilts with its acceleration like a quadrotor.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/geometry/pose.h"

namespace ag {

/// Where and how an agent moves (scenario key `path` of an agent).
struct PathOptions {
  std::string shape = "waypoints";          ///< waypoints, orbit or lawnmower
  std::vector<double> waypoints;            ///< waypoints: flat list x0, y0, x1, y1, ... (m, W)
  bool closed = true;                       ///< waypoints: loop back to the first point
  std::vector<double> center = {0.0, 0.0};  ///< orbit centre x, y (m)
  double radius_m = 10.0;                   ///< orbit radius (m)
  bool clockwise = false;                   ///< orbit / loop direction seen from above
  std::vector<double> area = {-10.0, -10.0, 10.0, 10.0};  ///< lawnmower xmin, ymin, xmax, ymax (m)
  double spacing_m = 6.0;                                 ///< lawnmower row spacing (m)
  double speed_mps = 1.0;                                 ///< cruise speed (m/s)
  double accel_time_s = 2.0;                 ///< time to reach cruise speed from rest (s)
  double start_offset_m = 0.0;               ///< start this far along the path (m)
  std::string heading = "tangent";           ///< tangent, look_at or fixed
  std::vector<double> look_at = {0.0, 0.0};  ///< look_at target x, y (m)
  double yaw_deg = 0.0;  ///< fixed: the yaw; tangent / look_at: added to the heading (deg)

  template <class V>
  void VisitFields(V& v) {
    v("shape", shape);
    v("waypoints", waypoints);
    v("closed", closed);
    v("center", center);
    v("radius_m", radius_m);
    v("clockwise", clockwise);
    v("area", area);
    v("spacing_m", spacing_m);
    v("speed_mps", speed_mps);
    v("accel_time_s", accel_time_s);
    v("start_offset_m", start_offset_m);
    v("heading", heading);
    v("look_at", look_at);
    v("yaw_deg", yaw_deg);
  }
  void Check() const;
};

/// Arc-length parameterised centripetal Catmull-Rom spline in the plane.
class SplinePath {
 public:
  SplinePath(std::vector<Eigen::Vector2d> points, bool closed);
  double length() const { return cumulative_.back(); }
  bool closed() const { return closed_; }
  /// Point at arc length s (closed: wraps; open: clamps to the ends).
  Eigen::Vector2d Position(double s) const;
  /// Points every `step_m` along the whole path.
  std::vector<Eigen::Vector2d> Sample(double step_m) const;

 private:
  Eigen::Vector2d Evaluate(int segment, double u) const;
  std::vector<Eigen::Vector2d> points_;
  bool closed_;
  int segments_ = 0;
  static constexpr int kSamplesPerSegment = 128;
  std::vector<double> cumulative_;  ///< arc length at sample k (segment k / N, u = (k % N) / N)
};

/// The waypoints a PathOptions describes.
std::vector<Eigen::Vector2d> PathWaypoints(const PathOptions& options);

/// True motion of one agent: T_W_body(tau) for true time tau (s) since the
/// start of the scenario.
class AgentMotion {
 public:
  /// `height_m`: body height above the ground (UGV) or flight altitude
  /// (UAV); `air`: tilt with acceleration; `altitude_variation_m`: slow
  /// altitude change (UAV); `vibration_deg`: small roll/pitch oscillation.
  AgentMotion(const PathOptions& path, bool air, double height_m, double altitude_variation_m,
              double vibration_deg, uint64_t seed);

  Pose BodyPose(double tau) const;
  /// Arc length travelled at tau (m).
  double ArcLength(double tau) const;
  const SplinePath& path() const { return spline_; }
  double height_m() const { return height_m_; }
  double altitude_variation_m() const { return altitude_variation_m_; }

 private:
  Eigen::Vector3d Position(double tau) const;
  double Yaw(double tau) const;

  PathOptions options_;
  SplinePath spline_;
  bool air_;
  double height_m_;
  double altitude_variation_m_;
  double vibration_rad_;
  double phases_[9] = {};
  double freqs_[9] = {};
};

}  // namespace ag
