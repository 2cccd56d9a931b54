#pragma once

// Online estimate of the UGV camera's rotation against the LiDAR map: the
// calibration error that stage 1 exists to absorb (paper, "Two-stage
// Optimization": extrinsic and time-offset errors between camera and LiDAR).
//
// Why a separate, run-long estimate: the camera-to-LiDAR rotation error is
// constant, but one sliding window of forward motion observes it badly (the
// common rotation of all window poses only shows through the short baseline),
// so per-window corrections scatter and trade pitch for roll. Map planes make
// it well observable: a keypoint's ray cut with the map surface gives a point
// whose position depends strongly on the ray's direction (at a grazing angle
// on the ground, 1 deg of pitch moves it metres), and that point must
// reproject onto the keypoint's match in the other keyframes. Collecting such
// plane-track observations over the whole run and solving for the one
// rotation that satisfies all of them gives a correction that improves as
// the UGV turns and sees more surfaces.
//
// Ceres stays inside camera_rotation.cc.

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "common/core/error.h"
#include "common/geometry/pose.h"
#include "ground_server/estimation/refinement.h"

namespace ag {

/// One observation of a map-plane point: the keypoint's ray in its host
/// keyframe, cut with the plane, must reproject onto its match in another
/// keyframe. Poses are as LIO and the nominal extrinsic give them.
struct PlaneTrackObservation {
  Pose T_wg_c_host = Pose::Identity();
  Eigen::Vector2d f_host = Eigen::Vector2d::Zero();  ///< undistorted normalised coords
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();   ///< (n, d), n.p + d = 0 in wg, |n| = 1
  Pose T_wg_c_obs = Pose::Identity();
  Eigen::Vector2d f_obs = Eigen::Vector2d::Zero();  ///< undistorted normalised coords
  double focal_px = 500;                            ///< whitening: normalised units to pixels
  /// Each camera's motion (UgvKeyframe::omega_c, v_wg), for the time offset.
  Eigen::Vector3d omega_host_c = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_host_wg = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_obs_c = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_obs_wg = Eigen::Vector3d::Zero();
};

class CameraRotationCalibrator {
 public:
  struct Options {
    bool enabled = true;           ///< off: stage 1's fused window correction is used instead
    int max_observations = 6000;   ///< a uniform sample of this many is kept (bounds the solve)
    int min_observations = 150;    ///< fewer: no correction yet
    double sigma_px = 1.0;         ///< keypoint noise (px)
    double prior_sigma_deg = 3.0;  ///< prior of the correction towards the nominal extrinsic (deg)
    /// Rays closer than this to the plane are not used (the cut is unstable).
    double min_ray_plane_angle_deg = 3.0;
    /// Residuals of wrong UGV-UGV matches reach the track gate (8 px), so
    /// the loss is Cauchy at 1 px: Huber still lets them pull linearly.
    RobustLossOptions loss{"cauchy", 1.0};
    /// Also estimate the camera's time offset against LIO, from how the
    /// residuals follow the UGV's turning and speed: a camera pose taken
    /// from LIO at the wrong time is off by the motion in between (15 ms at
    /// 10 deg/s is 0.15 deg), which a constant rotation cannot absorb.
    bool estimate_time_offset = true;
    double time_offset_prior_sigma_s = 0.05;  ///< prior towards the nominal offset (s)
    int max_iterations = 10;
    /// Re-solve once the observations offered since the last solve are this
    /// fraction of all offered so far: with the uniform sample, fewer new
    /// ones barely move the estimate, so solves get rarer as the run goes on.
    double resolve_fraction = 0.1;

    template <class V>
    void VisitFields(V& v) {
      v("enabled", enabled);
      v("max_observations", max_observations);
      v("min_observations", min_observations);
      v("sigma_px", sigma_px);
      v("prior_sigma_deg", prior_sigma_deg);
      v("min_ray_plane_angle_deg", min_ray_plane_angle_deg);
      v("loss", loss);
      v("estimate_time_offset", estimate_time_offset);
      v("time_offset_prior_sigma_s", time_offset_prior_sigma_s);
      v("max_iterations", max_iterations);
      v("resolve_fraction", resolve_fraction);
    }
    void Check() const;
  };

  struct SolveResult {
    bool updated = false;  ///< false: too few observations or the solve failed
    std::string reason;
    int observations = 0;
    double initial_rms_px = 0;  ///< robust cost as an rms reprojection error (px)
    double final_rms_px = 0;
  };

  CameraRotationCalibrator() = default;
  explicit CameraRotationCalibrator(const Options& options);

  /// Adds an observation once: `key` is (host keyframe id, host keypoint,
  /// observing keyframe id), so the same observation offered by consecutive
  /// windows counts once. Observations with a non-finite value or a ray
  /// (nearly) parallel to the plane are ignored. Returns true when added.
  bool Add(const std::tuple<int64_t, int, int64_t>& key, const PlaneTrackObservation& obs);

  /// Re-solves for the rotation over all kept observations, starting from
  /// the current one.
  SolveResult Solve();

  /// Rotation to apply on the right of a LIO camera pose
  /// (T_wg_c_corrected = T_wg_c * [R, 0]): R = R_c_nominal_c_true.
  const Eigen::Matrix3d& rotation() const { return rotation_; }
  /// Seconds to add to a UGV image's time (beyond the nominal offset) to
  /// get the LIO time of its pose; zero unless estimate_time_offset.
  double time_offset_s() const { return time_offset_s_; }
  bool has_estimate() const { return has_estimate_; }
  int num_observations() const { return static_cast<int>(observations_.size()); }

 private:
  Options options_;
  /// A uniform sample of all observations offered over the run (the
  /// rotation is constant, so old observations are as good as new ones and
  /// keep the estimate from following one stretch of road).
  std::vector<PlaneTrackObservation> observations_;
  uint64_t offered_ = 0;
  std::mt19937_64 rng_{1};  ///< fixed seed: the estimator stays deterministic
  /// Keys of recently added observations (an observation is offered again
  /// by every window that still holds both its keyframes).
  std::set<std::tuple<int64_t, int, int64_t>> keys_;
  std::deque<std::tuple<int64_t, int, int64_t>> recent_keys_;
  Eigen::Vector3d angle_axis_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation_ = Eigen::Matrix3d::Identity();
  double time_offset_s_ = 0;
  bool has_estimate_ = false;
  int added_since_solve_ = 0;
};

}  // namespace ag
