#pragma once

// Small geometry fixtures shared by tests that build synthetic scenes.

#include <Eigen/Geometry>
#include <vector>

#include "common/camera/camera_params.h"
#include "common/geometry/pose.h"

namespace ag::test {

/// A 640x480 pinhole camera with fx = fy = 500 and the centre in the middle.
inline CameraParams Pinhole640x480(std::vector<double> distortion = {}) {
  CameraParams p;
  p.width = 640;
  p.height = 480;
  p.fx = p.fy = 500;
  p.cx = 320;
  p.cy = 240;
  p.distortion = std::move(distortion);
  return p;
}

/// Camera pose T_w_c at `position` looking at `target` (OpenCV axes: z
/// forward, x to the right with no roll about the gravity axis).
inline Pose LookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - position).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Pose T = Pose::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = position;
  return T;
}

}  // namespace ag::test
