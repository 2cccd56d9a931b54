#include "air_agent/governor/bandwidth_governor.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/core/error.h"

namespace ag {

void BandwidthGovernor::Options::Check() const {
  CheckOption(std::isfinite(budget_mbps) && budget_mbps >= 0.0, "budget_mbps",
              "must be >= 0 (0 = unlimited)");
  CheckOption(max_keypoints > 0, "max_keypoints", "must be > 0");
  CheckOption(min_keypoints > 0 && min_keypoints <= max_keypoints, "min_keypoints",
              "must be in [1, max_keypoints]");
  CheckOption(!encodings.empty(), "encodings", "must name at least one encoding");
  CheckOption(max_packet_bytes >= 0, "max_packet_bytes", "must be >= 0 (0 = no limit)");
  for (const std::string& name : encodings) {
    CheckOption(ParseArrayEncoding(name).has_value(), "encodings",
                "has unknown encoding '" + name + "' (float32, float16, int8, bits4)");
  }
  CheckOption(window_s > 0.0, "window_s", "must be > 0");
  CheckOption(std::isfinite(keyframe_interval_s) && keyframe_interval_s >= 0.0,
              "keyframe_interval_s", "must be >= 0 (0 = one window)");
}

BandwidthGovernor::BandwidthGovernor(const Options& options, PacketBytesFn packet_bytes)
    : options_(options), packet_bytes_(std::move(packet_bytes)) {
  options_.Check();
  for (const std::string& name : options_.encodings)
    encodings_.push_back(*ParseArrayEncoding(name));
  window_ns_ = static_cast<int64_t>(std::llround(options_.window_s * 1e9));
  window_budget_bytes_ =
      static_cast<int64_t>(std::floor(options_.budget_mbps * 1e6 / 8.0 * options_.window_s));
  tokens_ = static_cast<double>(window_budget_bytes_);
}

double BandwidthGovernor::BucketDepth() {
  if (bucket_depth_ >= 0) return bucket_depth_;
  const double window = static_cast<double>(window_budget_bytes_);
  bucket_depth_ = window;
  if (options_.keyframe_interval_s > 0) {
    const double share = window * options_.keyframe_interval_s / options_.window_s;
    // Never below the smallest keyframe (and the reserve), or none would fit.
    const double smallest = static_cast<double>(
        packet_bytes_(std::min(options_.min_keypoints, options_.max_keypoints), encodings_.back()) +
        reserve_bytes_);
    bucket_depth_ = std::min(window, std::max(share, smallest));
  }
  return bucket_depth_;
}

void BandwidthGovernor::Refill(int64_t t_ns) {
  if (!started_) {
    started_ = true;
    last_refill_ns_ = t_ns;
    tokens_ = BucketDepth();
    return;
  }
  if (t_ns <= last_refill_ns_) return;
  const double rate_bytes_per_ns = static_cast<double>(window_budget_bytes_) / window_ns_;
  tokens_ = std::min<double>(
      BucketDepth(), tokens_ + rate_bytes_per_ns * static_cast<double>(t_ns - last_refill_ns_));
  last_refill_ns_ = t_ns;
}

int64_t BandwidthGovernor::BytesInWindow(int64_t t_ns) {
  // Trailing window (t - window, t].
  while (!sent_.empty() && sent_.front().first <= t_ns - window_ns_) {
    bytes_in_window_ -= sent_.front().second;
    sent_.pop_front();
  }
  return bytes_in_window_;
}

bool BandwidthGovernor::Fits(int64_t t_ns, int64_t bytes) {
  if (window_budget_bytes_ == 0) return true;
  return BytesInWindow(t_ns) + bytes <= window_budget_bytes_;
}

BandwidthGovernor::Plan BandwidthGovernor::PlanKeyframe(int64_t t_ns, int available_keypoints) {
  Plan plan;
  const int k_max = std::min(options_.max_keypoints, std::max(available_keypoints, 0));
  const int k_min = std::min(options_.min_keypoints, k_max);
  if (window_budget_bytes_ == 0 && options_.max_packet_bytes == 0) {
    plan.send = true;
    plan.keypoints = k_max;
    plan.encoding = encodings_.front();
    plan.bytes = packet_bytes_(plan.keypoints, plan.encoding);
    return plan;
  }
  int64_t allowance = std::numeric_limits<int64_t>::max();
  if (window_budget_bytes_ > 0) {
    Refill(t_ns);
    allowance = std::min<int64_t>(static_cast<int64_t>(std::floor(tokens_)),
                                  window_budget_bytes_ - BytesInWindow(t_ns)) -
                reserve_bytes_;
  }
  if (options_.max_packet_bytes > 0) allowance = std::min(allowance, options_.max_packet_bytes);
  for (size_t e = 0; e < encodings_.size(); ++e) {
    const ArrayEncoding encoding = encodings_[e];
    if (packet_bytes_(k_min, encoding) > allowance) continue;
    // Largest k in [k_min, k_max] that fits; packet size grows with k.
    int lo = k_min;
    int hi = k_max;
    while (lo < hi) {
      const int mid = lo + (hi - lo + 1) / 2;
      if (packet_bytes_(mid, encoding) <= allowance) {
        lo = mid;
      } else {
        hi = mid - 1;
      }
    }
    plan.send = true;
    plan.keypoints = lo;
    plan.encoding = encoding;
    plan.bytes = packet_bytes_(lo, encoding);
    if (lo < k_max) {
      plan.gave_up = "keypoints " + std::to_string(k_max) + " -> " + std::to_string(lo);
    }
    if (e > 0) {
      plan.gave_up += std::string(plan.gave_up.empty() ? "" : ", ") + "encoding " +
                      ToString(encodings_.front()) + " -> " + ToString(encoding);
    }
    return plan;
  }
  ++keyframes_skipped_;
  plan.gave_up = "keyframe skipped: " + std::to_string(packet_bytes_(k_min, encodings_.back())) +
                 " bytes needed at " + std::to_string(k_min) + " keypoints/" +
                 ToString(encodings_.back()) + ", " +
                 std::to_string(std::max<int64_t>(allowance, 0)) + " available";
  return plan;
}

bool BandwidthGovernor::TryConsume(int64_t t_ns, int64_t bytes) {
  if (window_budget_bytes_ == 0) return true;
  Refill(t_ns);
  if (!Fits(t_ns, bytes)) return false;
  sent_.emplace_back(t_ns, bytes);
  bytes_in_window_ += bytes;
  tokens_ -= static_cast<double>(bytes);
  return true;
}

}  // namespace ag
