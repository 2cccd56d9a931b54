#pragma once

// The relative-pose pipeline for one air agent (paper, Section III), callable
// without threads: retrieve co-visible UAV keyframes for the UGV sliding
// window, match descriptors, EPnP/4-DoF RANSAC, stage 1 (UGV window BA),
// stage 2 (4-DoF T_wa_wg with UAV poses), covariance, and the fix gate.

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/camera/camera.h"
#include "common/types/keyframe.h"
#include "ground_server/estimation/absolute_pose.h"
#include "ground_server/estimation/camera_rotation.h"
#include "ground_server/estimation/fix_filter.h"
#include "ground_server/estimation/fix_gate.h"
#include "ground_server/estimation/refinement.h"
#include "ground_server/matching/descriptor_matcher.h"

namespace ag {

/// A UGV keyframe after depth association.
struct UgvKeyframe {
  int64_t id = 0;                  ///< unique, increasing
  int64_t t_ns = 0;                ///< image time, ground clock
  Pose T_wg_c = Pose::Identity();  ///< camera pose interpolated from LIO
  /// The camera's motion at t_ns from LIO (zero when unknown): angular
  /// velocity in the camera frame (rad/s) and velocity in wg (m/s), for a
  /// time-offset correction.
  Eigen::Vector3d omega_c = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_wg = Eigen::Vector3d::Zero();
  LocalFeatures features;
  std::vector<float> global_descriptor;
  std::vector<Eigen::Vector3d> points_wg;  ///< per keypoint, meaningful where has_point
  std::vector<uint8_t> has_point;          ///< 1 when the LiDAR map gave the keypoint depth
  /// Per keypoint, the map surface at its point as (n, d) with n.p + d = 0,
  /// |n| = 1; all zero where the map is not flat there (or no point). Empty
  /// when the frontend computed none.
  std::vector<Eigen::Vector4d> planes_wg;
  /// Whether keypoint k lies on a map plane (false when none were computed).
  bool has_plane(int k) const { return !planes_wg.empty() && IsMapPlane(planes_wg[k]); }
};

/// The UGV sliding window, oldest keyframe first.
using UgvWindow = std::deque<std::shared_ptr<const UgvKeyframe>>;

/// Where UAV keyframes come from (the place database in the daemon).
class AirKeyframeSource {
 public:
  struct Candidate {
    std::shared_ptr<const AirKeyframe> keyframe;
    double similarity = 0;  ///< global-descriptor similarity (higher is closer)
  };
  virtual ~AirKeyframeSource() = default;
  /// Up to k keyframes of `agent` most similar to `global`.
  virtual std::vector<Candidate> Retrieve(const std::vector<float>& global,
                                          const std::string& agent, int k) const = 0;
  /// Up to n most recent keyframes of `agent`, newest first.
  virtual std::vector<std::shared_ptr<const AirKeyframe>> Recent(const std::string& agent,
                                                                 int n) const = 0;
};

/// Which of the frames taken at `t_ns` (any order) to keep so that they
/// span at most `span_s` seconds: the stretch holding the most `weight`
/// (ties: the later stretch). span_s == 0 keeps all.
std::vector<bool> StretchWithMostWeight(const std::vector<int64_t>& t_ns,
                                        const std::vector<int>& weight, double span_s);

/// The covariance (x, y, z, yaw; m^2, rad^2) of a bias that leaves where
/// `T_wa_wg` maps `pivot_wg` uncertain by sigma_t_m per axis, and its yaw by
/// sigma_yaw_rad about that point. An error of the UGV camera's calibration
/// seen through the map around the UGV turns the relation about the UGV, not
/// about the ground world's origin: at a distance L from the origin a yaw
/// error e moves the translation by L e, which this puts into the (x, y)
/// block together with its correlation with yaw.
Eigen::Matrix4d PivotedBiasCovariance(const Pose& T_wa_wg, const Eigen::Vector3d& pivot_wg,
                                      double sigma_t_m, double sigma_yaw_rad);

struct EstimatorOptions {
  int retrieval_k = 4;              ///< candidates retrieved per UGV window keyframe
  int recent_covisible = 3;         ///< also try this many newest UAV keyframes once fixed
  double covisible_fraction = 0.2;  ///< of UGV points inside the UAV image to count as co-visible
  int max_pairs = 12;               ///< air-ground keyframe pairs matched per estimate
  int min_matches = 20;             ///< a pair with fewer descriptor matches is discarded
  /// a pair with fewer RANSAC inliers gives no consistency term; a UAV keyframe with fewer is no
  /// new evidence for the fix gate
  int min_pair_inliers = 12;
  int min_inliers = 30;  ///< fewer inliers overall: no estimate
  /// The UAV keyframes of one estimate span at most this much of the UAV's
  /// time (s; 0 = no limit): the stretch with the most RANSAC inliers is
  /// kept. VIO drifts, so keyframes taken far apart in time (a UGV that
  /// sees what the UAV saw on several passes) disagree on T_wa_wg by that
  /// drift, and one estimate over all of them lands between their
  /// relations instead of at its newest keyframe's. With the UGV frontend's
  /// short camera-motion window, 10 s mapped the UGV 29% nearer to the
  /// truth on no_initial_covisibility and lowered the drift-free error on
  /// both presets (tools/evaluation/ACCURACY.md).
  double max_air_span_s = 10.0;
  bool use_stage1 = true;         ///< r_GC (UGV window BA); off for the ablation
  int stage1_extra_tracks = 100;  ///< map-plane points of the newest UGV keyframe added to stage 1
  /// Without camera_rotation: stage-1 camera corrections are averaged over
  /// up to this many windows (a running mean that then forgets slowly); 1
  /// uses each window's own.
  int stage1_fusion_windows = 30;
  /// Stage 1's run-long estimate of the UGV camera's rotation against the
  /// LiDAR map, from every window's map-plane tracks (camera_rotation.h).
  CameraRotationCalibrator::Options camera_rotation;
  /// Reported covariance = solver covariance + scatter of this many latest
  /// estimates (unmodelled, geometry-dependent errors).
  int scatter_window = 8;
  /// Added to the reported covariance: the bias a ~1 deg, 15 ms UGV camera
  /// calibration error leaves after stage 1 (measured on simulated data; see
  /// tools/evaluation/ACCURACY.md), as an uncertainty of where the UGV camera maps to and a
  /// yaw about that point (PivotedBiasCovariance). Lower it for a better
  /// calibrated UGV. Where the simulated fixes map the UGV they are 5.5 cm
  /// off in the median; with 0.06 m the NEES over the 10-seed runs of both
  /// presets is 0.9-1.0 in the mean, none beyond the 95% bound.
  double bias_sigma_t_m = 0.06;
  double bias_sigma_yaw_deg = 0.3;
  double track_gate_px = 8.0;  ///< UGV-UGV match must reproject within this (px)
  MatcherOptions matcher;
  RansacOptions ransac;
  Stage1Options stage1;
  Stage2Options stage2;
  FixGate::Options gate;
  /// How the estimates the gate accepts are fused into the published fix.
  FixFilter::Options fusion;

  template <class V>
  void VisitFields(V& v) {
    v("retrieval_k", retrieval_k);
    v("recent_covisible", recent_covisible);
    v("covisible_fraction", covisible_fraction);
    v("max_pairs", max_pairs);
    v("min_matches", min_matches);
    v("min_pair_inliers", min_pair_inliers);
    v("min_inliers", min_inliers);
    v("max_air_span_s", max_air_span_s);
    v("use_stage1", use_stage1);
    v("stage1_extra_tracks", stage1_extra_tracks);
    v("stage1_fusion_windows", stage1_fusion_windows);
    v("camera_rotation", camera_rotation);
    v("scatter_window", scatter_window);
    v("bias_sigma_t_m", bias_sigma_t_m);
    v("bias_sigma_yaw_deg", bias_sigma_yaw_deg);
    v("track_gate_px", track_gate_px);
    v("matcher", matcher);
    v("ransac", ransac);
    v("stage1", stage1);
    v("stage2", stage2);
    v("gate", gate);
    v("fusion", fusion);
  }
  void Check() const;
};

/// Wall-clock time of each step of one estimate (ms).
struct EstimateTiming {
  double retrieval_ms = 0;
  double matching_ms = 0;
  double ransac_ms = 0;
  double stage1_ms = 0;
  double stage1_tracking_ms = 0;  ///< part of stage1_ms: UGV-UGV track matching
  double stage2_ms = 0;
  double total_ms = 0;
};

struct EstimateResult {
  bool success = false;  ///< an estimate was computed (published or not: see gate)
  std::string reason;    ///< why not, when !success
  /// When published, the fix: this estimate fused with the ones accepted
  /// before it (FixFilter); otherwise this estimate alone.
  Pose T_wa_wg = Pose::Identity();
  /// (x, y, z, yaw), m^2 / rad^2: this estimate's (solver, scatter of recent
  /// estimates, bias floor), also for the fused fix: a conservative bound.
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  Pose T_wa_wg_single = Pose::Identity();  ///< this estimate alone, before fusion
  bool has_covariance = false;
  int inliers = 0;
  int pairs = 0;                  ///< air-ground keyframe pairs that contributed
  int candidates = 0;             ///< UAV keyframes considered
  int64_t newest_air_t_ns = 0;    ///< air clock time of the newest UAV keyframe used
  int64_t oldest_air_t_ns = 0;    ///< and of the oldest
  std::vector<int64_t> air_seqs;  ///< the UAV keyframes used (seq, ascending)
  double rms_reprojection_px = 0;
  Pose T_wa_wg_initial = Pose::Identity();  ///< RANSAC result, before refinement
  /// The newest UGV keyframe's camera pose from LIO and as used after stage 1
  /// (with the fused correction; equal when stage 1 never ran), for
  /// diagnostics.
  Pose ugv_T_wg_c_lio = Pose::Identity();
  Pose ugv_T_wg_c_refined = Pose::Identity();
  FixGate::Decision gate;  ///< whether this estimate is published, and the status
  EstimateTiming timing;
};

/// Estimates T_wa_wg for one air agent. Not thread-safe; one instance per
/// agent, so agents never wait for each other.
class AgentEstimator {
 public:
  AgentEstimator(std::string agent, const EstimatorOptions& options,
                 std::shared_ptr<const Camera> ugv_camera);

  /// Camera of the agent's keyframes with this camera_id (from camera_info).
  void SetAirCamera(const std::string& camera_id, std::shared_ptr<const Camera> camera);
  bool HasAirCamera(const std::string& camera_id) const;

  /// One estimate at ground time t_ns over the UGV window (oldest first).
  EstimateResult Estimate(int64_t t_ns, const UgvWindow& window, const AirKeyframeSource& source);

  const std::string& agent() const { return agent_; }
  const FixGate& gate() const { return gate_; }
  /// The UGV camera's correction against the LiDAR map that stage 1 applies
  /// (on the right of the LIO camera pose; identity until it has one).
  const Pose& camera_correction() const { return camera_correction_; }
  /// The UGV camera's time offset against LIO that stage 1 applies (s, as
  /// the dataset's time_offset_s: t_body = t_camera + offset, beyond the
  /// nominal one); 0 until estimated or when not estimated.
  double camera_time_offset_s() const { return camera_rotation_.time_offset_s(); }
  /// A UGV keyframe's camera pose with the calibration estimated so far
  /// (time offset, then rotation correction) applied.
  Pose CorrectedCameraPose(const UgvKeyframe& kf) const;

 private:
  // The steps of Estimate; the types are defined in the .cc.
  struct PairCandidate;
  struct AirGroundMatches;
  struct WindowTracks;

  /// Step 1: the (window keyframe, UAV keyframe) pairs to match, best first,
  /// at most max_pairs; empty with *why set when there is none.
  std::vector<PairCandidate> SelectPairs(const UgvWindow& window, const AirKeyframeSource& source,
                                         std::string* why) const;
  /// Step 2: every pair's descriptor matches (match_cache_) as UAV rays
  /// against UGV points.
  AirGroundMatches MatchPairs(const UgvWindow& window, const std::vector<PairCandidate>& pairs);
  /// Step 4, stage 1: the window BA over the inliers' UGV keypoints (and
  /// map-plane points of the newest keyframe), which also updates the
  /// camera calibration; returns every inlier's point as seen from the
  /// corrected cameras, keyed by (window index, keypoint).
  std::map<std::pair<int, int>, Eigen::Vector3d> RefineWindow(const UgvWindow& window,
                                                              const AirGroundMatches& matched,
                                                              const std::vector<int>& inliers,
                                                              EstimateTiming* timing);
  /// Stage 1's tracks: the inliers' UGV keypoints with depth, then points
  /// on map planes from the newest keyframe.
  WindowTracks CollectTracks(const UgvWindow& window, const AirGroundMatches& matched,
                             const std::vector<int>& inliers) const;
  /// Finds each track in the other window keyframes (UGV-UGV matches that
  /// reproject within track_gate_px of its LiDAR point).
  void ObserveTracks(const UgvWindow& window, WindowTracks* tracks) const;
  /// Without the calibrator: fuses this window's stage-1 camera correction
  /// into the running one.
  void FuseWindowCorrection(const UgvWindow& window, const Stage1Result& s1, size_t n_tracks);
  /// Feeds this window's map-plane tracks to camera_rotation_ and takes its
  /// new estimate as the camera correction.
  void UpdateCameraRotation(const UgvWindow& window, const std::vector<UgvTrack>& tracks,
                            const std::vector<std::pair<int, int>>& track_key);
  /// Adds this estimate to recent_estimates_ and returns their scatter
  /// (zero for fewer than three).
  Eigen::Matrix4d RecentScatter(const Pose& T_wa_wg);

  std::string agent_;
  EstimatorOptions options_;
  std::shared_ptr<const Camera> ugv_camera_;
  std::map<std::string, std::shared_ptr<const Camera>> air_cameras_;
  FixGate gate_;
  FixFilter filter_;
  /// The UGV camera's pose correction against the LiDAR map (camera frame,
  /// T_c_lio_c). The extrinsic error it absorbs is constant, so it is
  /// estimated over the run: by camera_rotation_ (default), or else as the
  /// running mean of stage-1 window corrections (correction_windows_).
  Pose camera_correction_ = Pose::Identity();
  int correction_windows_ = 0;
  CameraRotationCalibrator camera_rotation_;
  std::deque<Eigen::Vector4d> recent_estimates_;  ///< (x, y, z, yaw) of the latest estimates
  /// Descriptor matches of a (UGV keyframe, UAV keyframe) pair, `a` being
  /// the UGV keypoint and `b` the UAV keypoint, kept while the UGV keyframe is in
  /// the window: consecutive estimates share most pairs, and keyframes are
  /// immutable, so a pair is matched once. The entry holds both keyframes,
  /// so an address is never reused while it is a key.
  struct CachedMatches {
    std::shared_ptr<const UgvKeyframe> ugv;
    std::shared_ptr<const AirKeyframe> air;
    std::vector<DescriptorMatch> matches;
  };
  std::map<std::pair<const UgvKeyframe*, const AirKeyframe*>, CachedMatches> match_cache_;
};

}  // namespace ag
