#include "common/geometry/pose.h"

#include <algorithm>
#include <cmath>

namespace ag {

double YawOf(const Eigen::Matrix3d& R) { return std::atan2(R(1, 0), R(0, 0)); }

Eigen::Matrix3d RotZ(double yaw) {
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

double ProjectedYaw(const Eigen::Matrix3d& R) {
  return std::atan2(R(1, 0) - R(0, 1), R(0, 0) + R(1, 1));
}

Pose ProjectTo4Dof(const Pose& T) {
  Pose out = Pose::Identity();
  out.linear() = RotZ(ProjectedYaw(T.linear()));
  out.translation() = T.translation();
  return out;
}

Pose MakePose4Dof(double x, double y, double z, double yaw) {
  Pose out = Pose::Identity();
  out.linear() = RotZ(yaw);
  out.translation() = Eigen::Vector3d(x, y, z);
  return out;
}

double WrapAngle(double a) {
  a = std::remainder(a, 2.0 * M_PI);  // [-pi, pi]
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

bool IsRotation(const Eigen::Matrix3d& R, double tolerance) {
  if (!R.allFinite()) return false;
  const double ortho = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  return ortho <= tolerance && std::abs(R.determinant() - 1.0) <= tolerance;
}

Pose InterpolatePose(const Pose& a, const Pose& b, double s) {
  const Eigen::Quaterniond qa(a.linear());
  const Eigen::Quaterniond qb(b.linear());
  Pose out = Pose::Identity();
  out.linear() = qa.slerp(s, qb).toRotationMatrix();
  out.translation() = (1.0 - s) * a.translation() + s * b.translation();
  return out;
}

InterpolationResult InterpolateInBuffer(const std::vector<StampedPose>& sorted_poses,
                                        int64_t t_ns) {
  InterpolationResult result;
  if (sorted_poses.empty()) return result;
  if (t_ns < sorted_poses.front().t_ns) {
    result.status = InterpolationStatus::kBeforeStart;
    return result;
  }
  if (t_ns > sorted_poses.back().t_ns) {
    result.status = InterpolationStatus::kAfterEnd;
    return result;
  }
  // First element with time >= t_ns.
  const auto hi = std::lower_bound(sorted_poses.begin(), sorted_poses.end(), t_ns,
                                   [](const StampedPose& p, int64_t t) { return p.t_ns < t; });
  result.status = InterpolationStatus::kOk;
  if (hi->t_ns == t_ns) {
    result.T = hi->T;
    return result;
  }
  const auto lo = std::prev(hi);
  const double s = static_cast<double>(t_ns - lo->t_ns) / static_cast<double>(hi->t_ns - lo->t_ns);
  result.T = InterpolatePose(lo->T, hi->T, s);
  return result;
}

}  // namespace ag
