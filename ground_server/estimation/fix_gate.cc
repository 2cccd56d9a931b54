#include "ground_server/estimation/fix_gate.h"

#include <algorithm>
#include <cmath>

#include "common/core/error.h"

namespace ag {

const char* ToString(FixStatus status) {
  switch (status) {
    case FixStatus::kInitializing:
      return "initializing";
    case FixStatus::kTracking:
      return "tracking";
    case FixStatus::kLost:
      return "lost";
  }
  return "?";
}

void FixGate::Options::Check() const {
  CheckOption(confirmations >= 1, "confirmations", "must be >= 1");
  CheckOption(jump_confirmations >= 1, "jump_confirmations", "must be >= 1");
  CheckOption(agree_translation_m > 0, "agree_translation_m", "must be > 0");
  CheckOption(agree_yaw_deg > 0, "agree_yaw_deg", "must be > 0");
  CheckOption(lost_after_s > 0, "lost_after_s", "must be > 0");
  CheckOption(repeat_min_inlier_fraction >= 0, "repeat_min_inlier_fraction", "must be >= 0");
}

FixGate::FixGate(const Options& options) : options_(options) { options_.Check(); }

bool FixGate::Agree(const Pose& a, const Pose& b) const {
  const double dt = (a.translation() - b.translation()).norm();
  const double dyaw = std::abs(WrapAngle(ProjectedYaw(a.linear()) - ProjectedYaw(b.linear())));
  return dt <= options_.agree_translation_m && dyaw <= options_.agree_yaw_deg * M_PI / 180.0;
}

void FixGate::UpdateLost(int64_t t_ns) {
  if (status_ == FixStatus::kTracking && last_fix_t_ns_ &&
      1e-9 * static_cast<double>(t_ns - *last_fix_t_ns_) > options_.lost_after_s) {
    status_ = FixStatus::kLost;
  }
}

void FixGate::ResetCandidate() {
  candidate_.reset();
  candidate_count_ = 0;
  candidate_air_seqs_.clear();
}

FixGate::Decision FixGate::Offer(int64_t t_ns, const Pose& T_wa_wg, const FixEvidence& evidence) {
  const std::vector<int64_t>& air_seqs = evidence.air_seqs;
  Decision d;
  if (fix_ && status_ != FixStatus::kLost && Agree(T_wa_wg, *fix_)) {
    // Consistent with the current fix: publish at once.
    fix_ = T_wa_wg;
    last_fix_t_ns_ = t_ns;
    ResetCandidate();
    status_ = FixStatus::kTracking;
    d.publish = true;
    d.status = status_;
    return d;
  }
  // A first fix, a jump, or a re-acquisition after being lost: confirm it.
  bool repeated = false;  // agrees, but weakly and from UAV keyframes the chain has used
  if (candidate_ && Agree(T_wa_wg, *candidate_)) {
    repeated = evidence.inliers < options_.repeat_min_inlier_fraction * evidence.air_keypoints &&
               !air_seqs.empty() && std::all_of(air_seqs.begin(), air_seqs.end(), [&](int64_t seq) {
                 return candidate_air_seqs_.count(seq) > 0;
               });
    if (!repeated) ++candidate_count_;
  } else {
    candidate_count_ = 1;
    candidate_air_seqs_.clear();
  }
  candidate_ = T_wa_wg;
  candidate_air_seqs_.insert(air_seqs.begin(), air_seqs.end());
  const bool jump = fix_ && status_ != FixStatus::kLost;
  const int needed = jump ? options_.jump_confirmations : options_.confirmations;
  if (candidate_count_ >= needed) {
    d.new_fix = true;
    fix_ = T_wa_wg;
    last_fix_t_ns_ = t_ns;
    ResetCandidate();
    status_ = FixStatus::kTracking;
    d.publish = true;
    d.status = status_;
    return d;
  }
  UpdateLost(t_ns);
  d.status = status_;
  d.reason = std::string(fix_ ? "estimate disagrees with the current fix; " : "") +
             "awaiting confirmation " + std::to_string(candidate_count_) + "/" +
             std::to_string(needed) +
             (repeated ? " (agrees, but with " + std::to_string(evidence.inliers) +
                             " inliers from UAV keyframes already counted)"
                       : "");
  return d;
}

void FixGate::Refine(const Pose& T_wa_wg) {
  if (fix_) fix_ = T_wa_wg;
}

FixGate::Decision FixGate::Failed(int64_t t_ns) {
  UpdateLost(t_ns);
  Decision d;
  d.status = status_;
  d.reason = "no estimate";
  return d;
}

}  // namespace ag
