#pragma once

// Fuses the estimates the fix gate accepts into the published T_wa_wg.
//
// One estimate sees a few seconds of data, and where the UAV and the UGV see
// the same structure from afar its yaw and the translation across the view
// trade against each other (a yaw error about a far pivot is a translation):
// single estimates scatter along that ridge by up to metres, and the solver's
// covariance says so. The worlds' true relation changes only with the two
// odometries' drift, so successive estimates measure (nearly) one quantity:
// a Kalman filter with a random-walk state (the drift) and each estimate's
// covariance as its noise averages the scatter away, weighting each by how
// well its geometry determines each direction.

#include <Eigen/Core>
#include <cstdint>
#include <optional>

#include "common/geometry/pose.h"

namespace ag {

class FixFilter {
 public:
  struct Options {
    bool enabled = true;  ///< off: every accepted estimate is published as it is
    /// Random walk of the true relation (odometry drift), per sqrt(s) of
    /// UGV plus UAV time (Update): 0.04 m/sqrt(s) is 0.3 m over a minute.
    double drift_translation_m = 0.04;
    double drift_yaw_deg = 0.05;  ///< ... yaw (deg/sqrt(s)); 0.4 deg over a minute
    /// Consecutive estimates share most of their data (the same UAV
    /// keyframes, all but one UGV keyframe), so their errors are correlated:
    /// each counts as this fraction of an independent measurement (its
    /// covariance is divided by it).
    double weight = 0.25;

    template <class V>
    void VisitFields(V& v) {
      v("enabled", enabled);
      v("drift_translation_m", drift_translation_m);
      v("drift_yaw_deg", drift_yaw_deg);
      v("weight", weight);
    }
    void Check() const;
  };

  explicit FixFilter(const Options& options);

  /// Starts over from one estimate (a first fix, or a confirmed jump).
  void Reset(int64_t t_ns, const Pose& T_wa_wg, const Eigen::Matrix4d& covariance,
             int64_t air_t_ns = 0);
  /// Fuses an estimate made at t_ns with covariance (x, y, z, yaw; m^2, rad^2).
  /// Starts over when there is no state yet or when t_ns is not after the last.
  /// air_t_ns: the UAV time the estimate's relation holds at (its newest UAV
  /// keyframe). The relation drifts with both odometries, so the random walk
  /// runs over the UGV's time since the last estimate plus the UAV's between
  /// the two estimates' keyframes, which jumps when an estimate is made from
  /// keyframes of another pass.
  void Update(int64_t t_ns, const Pose& T_wa_wg, const Eigen::Matrix4d& covariance,
              int64_t air_t_ns = 0);

  /// The fused relation (4-DoF: rotation about z only).
  Pose T_wa_wg() const;
  /// Its covariance (x, y, z, yaw), as the filter models it. Where the
  /// errors of successive estimates stay alike for longer than `weight`
  /// allows for it is too small, so AgentEstimator publishes the estimate's
  /// own covariance with the fused fix.
  const Eigen::Matrix4d& covariance() const { return P_; }

 private:
  Options options_;
  std::optional<int64_t> t_ns_;
  int64_t air_t_ns_ = 0;
  Eigen::Vector4d x_ = Eigen::Vector4d::Zero();
  Eigen::Matrix4d P_ = Eigen::Matrix4d::Zero();
};

}  // namespace ag
