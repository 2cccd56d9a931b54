#include "air_agent/keyframe/keyframe_selector.h"

#include <cmath>

#include "common/core/error.h"

namespace ag {

void KeyframeSelector::Options::Check() const {
  CheckOption(period_s >= 0.0, "period_s", "must be >= 0");
  CheckOption(min_translation_m >= 0.0, "min_translation_m", "must be >= 0");
  CheckOption(min_rotation_deg >= 0.0, "min_rotation_deg", "must be >= 0");
  CheckOption(min_interval_s >= 0.0, "min_interval_s", "must be >= 0");
  CheckOption(period_s > 0.0 || min_translation_m > 0.0 || min_rotation_deg > 0.0, "period_s",
              "and the motion thresholds are all 0: no frame would ever be a keyframe");
}

KeyframeSelector::KeyframeSelector(const Options& options) : options_(options) { options_.Check(); }

KeyframeSelector::Decision KeyframeSelector::Consider(int64_t t_ns, const Pose& T_w_c) {
  Decision d;
  if (!last_t_ns_) {
    d.reason = Reason::kFirst;
  } else {
    const double dt = 1e-9 * static_cast<double>(t_ns - *last_t_ns_);
    if (dt < options_.min_interval_s || dt <= 0.0) return d;
    const Pose delta = last_T_w_c_.inverse() * T_w_c;
    const double moved = delta.translation().norm();
    const double turned = Eigen::AngleAxisd(delta.linear()).angle() * 180.0 / M_PI;
    if (options_.period_s > 0.0 && dt >= options_.period_s - 1e-9) {
      d.reason = Reason::kTime;
    } else if (options_.min_translation_m > 0.0 && moved >= options_.min_translation_m) {
      d.reason = Reason::kTranslation;
    } else if (options_.min_rotation_deg > 0.0 && turned >= options_.min_rotation_deg) {
      d.reason = Reason::kRotation;
    } else {
      return d;
    }
  }
  d.is_keyframe = true;
  previous_t_ns_ = last_t_ns_;
  previous_T_w_c_ = last_T_w_c_;
  last_t_ns_ = t_ns;
  last_T_w_c_ = T_w_c;
  return d;
}

void KeyframeSelector::Reject() {
  last_t_ns_ = previous_t_ns_;
  last_T_w_c_ = previous_T_w_c_;
}

const char* ToString(KeyframeSelector::Reason reason) {
  switch (reason) {
    case KeyframeSelector::Reason::kNone:
      return "none";
    case KeyframeSelector::Reason::kFirst:
      return "first";
    case KeyframeSelector::Reason::kTime:
      return "time";
    case KeyframeSelector::Reason::kTranslation:
      return "translation";
    case KeyframeSelector::Reason::kRotation:
      return "rotation";
  }
  return "?";
}

}  // namespace ag
