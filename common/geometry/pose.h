#pragma once

// Frame convention of the whole project (see STYLE.md):
//   T_a_b maps a point from frame b into frame a: p_a = T_a_b * p_b.
//   Points are named by their frame: p_in_wg, p_c.
//   Worlds are gravity-aligned, z up: wa (an air agent's VIO world), wg (the
//   ground agent's LIO world). Cameras follow OpenCV (x right, y down, z fwd).
// Time is int64_t nanoseconds (t_ns) in each agent's own clock.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

namespace ag {

/// A rigid transform T_a_b (rotation + translation).
using Pose = Eigen::Isometry3d;

/// A pose at a time, as odometry reports it (T_world_body at t_ns).
struct StampedPose {
  int64_t t_ns = 0;
  Pose T = Pose::Identity();
};

/// Yaw (rotation about world z) of R under the z-y'-x'' (yaw-pitch-roll)
/// convention, in radians, (-pi, pi].
double YawOf(const Eigen::Matrix3d& R);

/// Rotation about z by `yaw` radians.
Eigen::Matrix3d RotZ(double yaw);

/// The rotation about z closest to R in the Frobenius norm:
/// argmax_yaw trace(RotZ(yaw)^T R) = atan2(R10 - R01, R00 + R11).
/// Exact (returns R itself) when R is already a rotation about z, which is
/// the case for T_wa_wg between two gravity-aligned worlds.
double ProjectedYaw(const Eigen::Matrix3d& R);

/// Projects a 6-DoF transform onto 4 DoF (x, y, z, yaw): keeps the
/// translation, replaces the rotation by RotZ(ProjectedYaw(R)).
Pose ProjectTo4Dof(const Pose& T);

/// A 4-DoF transform from x, y, z (m) and yaw (rad).
Pose MakePose4Dof(double x, double y, double z, double yaw);

/// Wraps an angle to (-pi, pi].
double WrapAngle(double a);

/// True when R is orthonormal with determinant +1 within `tolerance`
/// (max abs entry of R^T R - I, and |det - 1|).
bool IsRotation(const Eigen::Matrix3d& R, double tolerance = 1e-6);

/// Interpolates between two poses: linear in translation, slerp in rotation.
/// s = 0 gives a, s = 1 gives b.
Pose InterpolatePose(const Pose& a, const Pose& b, double s);

/// Why a buffered interpolation has no answer.
enum class InterpolationStatus {
  kOk,
  kEmpty,        ///< the buffer holds no pose
  kBeforeStart,  ///< t is earlier than the first pose (never extrapolated)
  kAfterEnd,     ///< t is later than the last pose: wait for more odometry
};

struct InterpolationResult {
  InterpolationStatus status = InterpolationStatus::kEmpty;
  Pose T = Pose::Identity();
  bool ok() const { return status == InterpolationStatus::kOk; }
};

/// Pose at t_ns from a buffer sorted by strictly increasing t_ns, by
/// InterpolatePose between the two neighbours. Exact hits return the stored
/// pose. Outside [front, back] the status says which side; no extrapolation.
InterpolationResult InterpolateInBuffer(const std::vector<StampedPose>& sorted_poses, int64_t t_ns);

}  // namespace ag
