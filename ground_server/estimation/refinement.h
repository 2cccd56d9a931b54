#pragma once

// The two refinement stages of the paper (Section "Two-stage Optimization"),
// callable without threads on plain structs. Ceres stays inside refinement.cc.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/camera/camera.h"
#include "common/geometry/pose.h"

namespace ag {

/// Robust loss choice shared by both stages.
struct RobustLossOptions {
  std::string type = "huber";  ///< "huber", "cauchy" or "none"
  double scale = 2.0;          ///< in whitened units (sigmas)

  template <class V>
  void VisitFields(V& v) {
    v("type", type);
    v("scale", scale);
  }
  void Check() const;
};

// ---------------------------------------------------------------- stage 1

/// One UGV keyframe of the sliding window.
struct UgvWindowFrame {
  int64_t t_ns = 0;
  Pose T_wg_c = Pose::Identity();  ///< from LIO interpolation (initial value and prior)
  const Camera* camera = nullptr;
};

/// True when `plane` holds a map surface (n, d) with |n| = 1; planes are all
/// zero where the map is not flat.
inline bool IsMapPlane(const Eigen::Vector4d& plane) { return plane.head<3>().squaredNorm() > 0.5; }

/// A map point tracked over UGV keyframes of the window.
struct UgvTrack {
  int host_frame = 0;      ///< frame whose ray anchors the point
  Eigen::Vector2d f_host;  ///< undistorted normalised coords in the host
  double lidar_depth = 0;  ///< z-depth in the host camera from the LiDAR map (m)
  /// The map surface at the point, (n, d) with n.p + d = 0 in wg, |n| = 1;
  /// zero when the map is not flat there.
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();
  bool has_plane() const { return IsMapPlane(plane); }
  /// (frame, pixel) of every other observation.
  std::vector<std::pair<int, Eigen::Vector2d>> observations;
};

struct Stage1Options {
  double sigma_px = 1.0;           ///< keypoint noise (px)
  double depth_sigma_m = 0.05;     ///< LiDAR depth prior (m)
  double lio_sigma_t_m = 0.02;     ///< LIO relative translation between keyframes (m)
  double lio_sigma_rot_deg = 0.2;  ///< LIO relative rotation between keyframes (deg)
  /// Anchor points to the LiDAR map surface (point-to-plane) and let the whole
  /// window move against the map, so a camera-LiDAR extrinsic or time-offset
  /// error is corrected instead of being frozen into the gauge frame.
  bool anchor_to_map = true;
  double plane_sigma_m = 0.03;  ///< point-to-plane (map noise and plane fit) (m)
  int min_plane_tracks = 15;    ///< fewer multi-view tracks on planes: gauge by the oldest pose
  /// With map anchoring, the gauge is fixed by the map and by a prior of
  /// every window pose towards its LIO-interpolated value, as loose as the
  /// expected calibration error.
  double pose_prior_sigma_t_m = 0.05;
  double pose_prior_sigma_rot_deg = 1.5;
  RobustLossOptions loss;
  int max_iterations = 8;  ///< Levenberg-Marquardt iterations (5 gave the same fixes as 20)

  template <class V>
  void VisitFields(V& v) {
    v("sigma_px", sigma_px);
    v("depth_sigma_m", depth_sigma_m);
    v("lio_sigma_t_m", lio_sigma_t_m);
    v("lio_sigma_rot_deg", lio_sigma_rot_deg);
    v("anchor_to_map", anchor_to_map);
    v("plane_sigma_m", plane_sigma_m);
    v("min_plane_tracks", min_plane_tracks);
    v("pose_prior_sigma_t_m", pose_prior_sigma_t_m);
    v("pose_prior_sigma_rot_deg", pose_prior_sigma_rot_deg);
    v("loss", loss);
    v("max_iterations", max_iterations);
  }
  void Check() const;
};

struct Stage1Result {
  bool success = false;
  std::string reason;
  std::vector<Pose> T_wg_c;                ///< refined UGV camera poses
  std::vector<Eigen::Vector3d> points_wg;  ///< refined point per track
  std::vector<double> depths;              ///< refined host depth per track
  double initial_cost = 0;
  double final_cost = 0;
  int iterations = 0;
  bool anchored_to_map = false;  ///< gauge from the map (else the oldest pose was held)
  int plane_tracks = 0;          ///< multi-view tracks with a point-to-plane term
};

/// Sliding-window bundle adjustment of UGV camera poses and map points in
/// inverse-depth form, with LIO relative-motion priors. Points on a flat
/// map surface are held to it (point-to-plane), the others by their LiDAR
/// depth. Gauge, explicitly: with enough multi-view plane tracks the map
/// fixes it (plus a loose prior of each pose towards LIO), so the window as
/// a whole can move against the map and absorb the camera's extrinsic and
/// time-offset error; otherwise the oldest keyframe's pose is held constant
/// and the window is refined relative to it.
Stage1Result RunStage1(const std::vector<UgvWindowFrame>& frames,
                       const std::vector<UgvTrack>& tracks, const Stage1Options& options);

// ---------------------------------------------------------------- stage 2

/// One UAV keyframe involved in the estimate.
struct AirFrame {
  int64_t t_ns = 0;
  Pose T_wa_c = Pose::Identity();  ///< from VIO (initial value and prior)
  const Camera* camera = nullptr;
};

/// A ground point (after stage 1) seen by a UAV keyframe.
struct AirGroundObservation {
  int air_frame = 0;
  Eigen::Vector3d p_wg;
  Eigen::Vector2d uv;  ///< UAV pixel (distorted, px)
};

/// One air-ground keyframe pair's own estimate, for the consistency term.
struct PairEstimate {
  int air_frame = 0;
  Pose T_ca_wg = Pose::Identity();  ///< that pair's PnP result
  double weight = 1.0;              ///< e.g. sqrt(inliers / 20); scales the information
};

struct Stage2Options {
  bool use_reprojection = true;            ///< r_CGCA (paper eq. agreproj)
  bool use_consistency = true;             ///< r_WAWG (paper eq. gcon)
  double sigma_px = 1.0;                   ///< UAV keypoint noise (px)
  double consistency_sigma_t_m = 0.2;      ///< spread of per-pair estimates (m)
  double consistency_sigma_yaw_deg = 1.0;  ///< spread of per-pair estimates (deg)
  double vio_sigma_t_per_s = 0.01;         ///< VIO relative drift (m per s between keyframes)
  double vio_sigma_rot_deg_per_s = 0.02;   ///< VIO relative drift (deg per s)
  double vio_sigma_floor_t_m = 0.002;      ///< minimum relative translation sigma (m)
  double vio_sigma_floor_rot_deg = 0.02;   ///< minimum relative rotation sigma (deg)
  RobustLossOptions loss;
  int max_iterations = 30;
  bool compute_covariance = true;

  template <class V>
  void VisitFields(V& v) {
    v("use_reprojection", use_reprojection);
    v("use_consistency", use_consistency);
    v("sigma_px", sigma_px);
    v("consistency_sigma_t_m", consistency_sigma_t_m);
    v("consistency_sigma_yaw_deg", consistency_sigma_yaw_deg);
    v("vio_sigma_t_per_s", vio_sigma_t_per_s);
    v("vio_sigma_rot_deg_per_s", vio_sigma_rot_deg_per_s);
    v("vio_sigma_floor_t_m", vio_sigma_floor_t_m);
    v("vio_sigma_floor_rot_deg", vio_sigma_floor_rot_deg);
    v("loss", loss);
    v("max_iterations", max_iterations);
    v("compute_covariance", compute_covariance);
  }
  void Check() const;
};

struct Stage2Result {
  bool success = false;
  std::string reason;
  Pose T_wa_wg = Pose::Identity();
  /// Covariance of (x, y, z, yaw) in m^2 / rad^2, scaled by the reduced
  /// chi-square when that exceeds 1 (so it never claims more certainty than
  /// the residuals support). Valid when has_covariance.
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  bool has_covariance = false;
  std::vector<Pose> T_wa_c;  ///< refined UAV camera poses
  double rms_reprojection_px = 0;
  int iterations = 0;
};

/// Optimises the 4-DoF T_wa_wg and the UAV camera poses with the ground
/// fixed: air-ground reprojection (robust), relative-pose consistency over
/// all pairs, and VIO relative-motion priors between UAV keyframes (time
/// ordered) so that UAV poses cannot wander. Gauge: the air world is defined
/// by VIO, so the newest UAV keyframe's pose is held constant.
Stage2Result RunStage2(const Pose& T_wa_wg_initial, const std::vector<AirFrame>& air_frames,
                       const std::vector<AirGroundObservation>& observations,
                       const std::vector<PairEstimate>& pairs, const Stage2Options& options);

}  // namespace ag
