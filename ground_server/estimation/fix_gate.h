#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/geometry/pose.h"

namespace ag {

/// What a relative-pose output says about its estimate.
enum class FixStatus { kInitializing, kTracking, kLost };
const char* ToString(FixStatus status);

/// What an estimate offered to FixGate was made from.
struct FixEvidence {
  /// the UAV keyframes the estimate rests on (AgentEstimator: those holding
  /// min_pair_inliers of its inliers; empty: unknown)
  std::vector<int64_t> air_seqs;
  int inliers = 0;           ///< the estimate's inliers on those keyframes
  double air_keypoints = 0;  ///< keypoints per keyframe of air_seqs, mean
};

/// Decides which estimates become published fixes, so that one aliased
/// match cannot produce a false fix: a first fix, or an estimate far from
/// the current fix, is published only after `confirmations` (a jump:
/// `jump_confirmations`) consecutive estimates agree with it; estimates close to the current fix
/// are published at once. Without any accepted estimate for `lost_after_s` the status becomes lost
/// (the last fix is still reported).
///
/// An agreeing estimate made only from UAV keyframes that earlier estimates
/// in the chain already used repeats their match rather than checks it: it
/// confirms only when strong, with at least `repeat_min_inlier_fraction`
/// inliers per keypoint of those UAV keyframes, which an aliased place,
/// alike only in part, rarely gives.
class FixGate {
 public:
  struct Options {
    /// Consecutive agreeing estimates for a new fix. Consecutive estimates
    /// share most of their data, so two can be wrong together: with 2, 6
    /// wrong first fixes were published over 10 no_initial_covisibility
    /// seeds, with 3 one (tools/evaluation/ACCURACY.md).
    int confirmations = 3;
    /// ... to replace a current fix (a jump), for the same reason
    int jump_confirmations = 3;
    double agree_translation_m = 0.3;  ///< estimates closer than this agree (m)
    double agree_yaw_deg = 2.0;        ///< ... and closer than this in yaw (deg)
    double lost_after_s = 10.0;        ///< no accepted estimate for this long: lost (s)
    /// An agreeing estimate from only UAV keyframes the chain has used
    /// confirms only with this many inliers per keypoint of those keyframes
    /// (0: always). Without it, at 512 keypoints three estimates of 56-63
    /// inliers on the same aliased UAV keyframes (the third 56 of 512, 0.11
    /// per keypoint) published a 39 m false first fix (tools/evaluation/ACCURACY.md).
    double repeat_min_inlier_fraction = 0.15;

    template <class V>
    void VisitFields(V& v) {
      v("confirmations", confirmations);
      v("jump_confirmations", jump_confirmations);
      v("agree_translation_m", agree_translation_m);
      v("agree_yaw_deg", agree_yaw_deg);
      v("lost_after_s", lost_after_s);
      v("repeat_min_inlier_fraction", repeat_min_inlier_fraction);
    }
    void Check() const;
  };

  struct Decision {
    bool publish = false;  ///< this estimate becomes the published fix
    /// A first fix, a confirmed jump or a re-acquisition after being lost,
    /// rather than a continuation of the current fix.
    bool new_fix = false;
    FixStatus status = FixStatus::kInitializing;
    std::string reason;  ///< e.g. "awaiting confirmation 1/2"
  };

  explicit FixGate(const Options& options);

  /// Offers a successful estimate made at t_ns (ground clock). Without
  /// evidence (empty air_seqs) every agreeing estimate confirms.
  Decision Offer(int64_t t_ns, const Pose& T_wa_wg, const FixEvidence& evidence = {});
  /// Records that an estimation at t_ns failed (no fix candidate).
  Decision Failed(int64_t t_ns);
  /// Replaces the current fix by a better value of it (the fused one), which
  /// later estimates are then compared with. No-op without a fix.
  void Refine(const Pose& T_wa_wg);

  FixStatus status() const { return status_; }
  const std::optional<Pose>& fix() const { return fix_; }
  std::optional<int64_t> last_fix_t_ns() const { return last_fix_t_ns_; }

 private:
  bool Agree(const Pose& a, const Pose& b) const;
  void UpdateLost(int64_t t_ns);
  /// Forgets the unconfirmed chain.
  void ResetCandidate();

  Options options_;
  FixStatus status_ = FixStatus::kInitializing;
  std::optional<Pose> fix_;
  std::optional<int64_t> last_fix_t_ns_;
  std::optional<Pose> candidate_;  ///< newest unconfirmed estimate
  int candidate_count_ = 0;
  std::set<int64_t> candidate_air_seqs_;  ///< UAV keyframes the chain has used
};

}  // namespace ag
