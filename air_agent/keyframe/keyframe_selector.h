#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "common/geometry/pose.h"

namespace ag {

/// Decides which camera frames become keyframes: by time (the paper sends
/// one per second) and, optionally, by motion since the last keyframe so
/// that fast flight still yields overlapping views.
class KeyframeSelector {
 public:
  struct Options {
    double period_s = 1.0;           ///< a keyframe at least this often (s); 0 disables
    double min_translation_m = 0.0;  ///< also when moved this far (m); 0 disables
    double min_rotation_deg = 0.0;   ///< also when turned this much (deg); 0 disables
    double min_interval_s = 0.2;     ///< never two keyframes closer than this (s)

    template <class V>
    void VisitFields(V& v) {
      v("period_s", period_s);
      v("min_translation_m", min_translation_m);
      v("min_rotation_deg", min_rotation_deg);
      v("min_interval_s", min_interval_s);
    }
    void Check() const;
  };

  enum class Reason { kNone, kFirst, kTime, kTranslation, kRotation };

  struct Decision {
    bool is_keyframe = false;
    Reason reason = Reason::kNone;
  };

  explicit KeyframeSelector(const Options& options);

  /// Considers the frame at t_ns with camera pose T_w_c (from odometry).
  /// Frames must come in increasing time; an older frame is never a keyframe.
  Decision Consider(int64_t t_ns, const Pose& T_w_c);

  /// Records that the caller really sent (or could not send) the last
  /// keyframe; a skipped keyframe leaves the reference frame unchanged so
  /// the next frame is considered again.
  void Reject();

  const Options& options() const { return options_; }

 private:
  Options options_;
  std::optional<int64_t> last_t_ns_;
  Pose last_T_w_c_ = Pose::Identity();
  std::optional<int64_t> previous_t_ns_;  ///< reference before the last acceptance
  Pose previous_T_w_c_ = Pose::Identity();
};

const char* ToString(KeyframeSelector::Reason reason);

}  // namespace ag
