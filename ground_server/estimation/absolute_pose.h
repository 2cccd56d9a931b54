#pragma once

// Initial estimate of T_wa_wg from air pixels matched to ground 3-D points.
//
// Each correspondence k gives a ground-world point p_wg (a UGV keypoint with
// LiDAR depth) and the unit bearing f_ca of the matched UAV keypoint in the
// UAV camera at pose T_wa_ca (from VIO). Then, for the true T_wa_wg,
//   T_wa_wg * p_wg = c + lambda * b,   c = t_wa_ca, b = R_wa_ca * f_ca, lambda > 0.
//
// Two solvers, both inside the same RANSAC loop:
//  * EPnP (OpenCV) on one UAV frame's pixels, composed with the VIO pose and
//    projected to 4 DoF afterwards (the paper's initial estimate);
//  * a 4-DoF minimal solver that uses the known vertical of the two
//    gravity-aligned worlds: 2 correspondences, any number of UAV frames.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "common/geometry/pose.h"

namespace ag {

/// One air pixel / ground point correspondence, already lifted to a ray.
struct RayPointCorrespondence {
  Eigen::Vector3d p_wg;           ///< ground-world 3-D point (m)
  Eigen::Vector3d c_wa;           ///< UAV camera centre in the air world (m)
  Eigen::Vector3d b_wa;           ///< unit bearing of the UAV keypoint, in air-world axes
  int air_frame = 0;              ///< index of the UAV keyframe (for per-frame solvers)
  Eigen::Vector2d uv;             ///< the UAV pixel (px), for reprojection scoring
  Eigen::Vector2d xy_normalized;  ///< undistorted normalised coords of uv
};

/// Solutions of the 4-DoF minimal problem from two correspondences
/// (0, 1 or 2 real solutions). Each is T_wa_wg = [RotZ(yaw) | t].
///
/// Derivation: with q = RotZ(yaw) p + t, the constraint (q - c) x b = 0 is
/// linear in y = (cos yaw, sin yaw, tx, ty, tz, 1): two independent rows per
/// correspondence, so two correspondences give a 4 x 6 system M y = 0 whose
/// null space is 2-D, y = a v1 + b v2. The conditions y6 = 1 and
/// y1^2 + y2^2 = 1 leave a quadratic in one unknown.
std::vector<Pose> SolveFourDofMinimal(const RayPointCorrespondence& a,
                                      const RayPointCorrespondence& b);

/// Angle (rad) between the ray of a correspondence and the direction to the
/// transformed point, or +inf when the point is behind the camera. The RANSAC
/// inlier test uses it converted to pixels with the focal length.
double AngularError(const Pose& T_wa_wg, const RayPointCorrespondence& c);

struct RansacOptions {
  std::string solver = "four_dof";   ///< "four_dof" (2-point, known gravity) or "epnp"
  double inlier_threshold_px = 3.0;  ///< reprojection threshold (px at the UAV focal length)
  int max_iterations = 2000;         ///< hard cap on hypotheses
  double confidence = 0.999999;      ///< stop early at this probability of success
  int min_inliers = 12;              ///< fewer means failure
  uint64_t seed = 1;                 ///< RANSAC is deterministic for a seed

  template <class V>
  void VisitFields(V& v) {
    v("solver", solver);
    v("inlier_threshold_px", inlier_threshold_px);
    v("max_iterations", max_iterations);
    v("confidence", confidence);
    v("min_inliers", min_inliers);
    v("seed", seed);
  }
  void Check() const;
};

struct AbsolutePoseResult {
  bool success = false;
  std::string reason;               ///< why not, when !success
  Pose T_wa_wg = Pose::Identity();  ///< 4-DoF (rotation about z only)
  std::vector<int> inliers;         ///< indices into the correspondences
  int iterations = 0;
};

/// Robust 4-DoF T_wa_wg from correspondences (any number of UAV frames).
/// `focal_px` converts the pixel threshold into an angle. The four_dof
/// solver samples pairs over all frames; epnp runs EPnP + RANSAC per UAV
/// frame (needs `T_wa_ca` of each frame, indexed by air_frame) and keeps the
/// frame whose 4-DoF projection has the most inliers over all frames. Both
/// finish with a least-squares 4-DoF refinement on the inliers.
AbsolutePoseResult EstimateAbsolutePose(const std::vector<RayPointCorrespondence>& correspondences,
                                        const std::vector<Pose>& T_wa_ca, double focal_px,
                                        const RansacOptions& options);

/// Gauss-Newton refinement of a 4-DoF T_wa_wg minimising the tangent-plane
/// (normalised image) error of the given correspondences in their cameras.
Pose RefineFourDof(const Pose& T_wa_wg, const std::vector<RayPointCorrespondence>& correspondences,
                   const std::vector<int>& indices, const std::vector<Pose>& T_wa_ca,
                   int iterations = 10);

}  // namespace ag
