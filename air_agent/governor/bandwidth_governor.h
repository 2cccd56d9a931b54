#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "common/wire/encoding.h"

namespace ag {

/// Keeps the air agent's traffic under a bandwidth budget.
///
/// Two mechanisms, measured on the bytes the link really carries (see
/// LcmLinkBytes): a token bucket (rate = budget, depth = one window of
/// budget) chooses how rich each keyframe packet may be, so the sending
/// rate settles at the budget; and a hard check over the trailing window
/// guarantees that no `window_s` interval ever carries more than the budget
/// (checking the window that ends at each send is enough: any window's bytes
/// are bounded by the trailing window of its last packet).
///
/// When a full packet does not fit it gives up, in this order: keypoints
/// (the best-scored are kept, down to `min_keypoints`), then the descriptor
/// encoding (next in `encodings`), then the keyframe itself (the keyframe
/// rate drops). Each plan says what it gave up so the daemon can log it.
class BandwidthGovernor {
 public:
  struct Options {
    double budget_mbps = 0.0;  ///< link budget (Mbit/s, 1e6 bit/s); 0 = unlimited
    int max_keypoints = 1024;  ///< keypoints per keyframe when the budget allows
    int min_keypoints = 256;   ///< lower the encoding rather than go below this
    /// Descriptor encodings tried in order, richest first.
    std::vector<std::string> encodings = {"int8", "bits4"};
    double window_s = 1.0;  ///< the interval over which the budget holds (s)
    /// Largest keyframe packet on the link (IPv4 bytes; 0 = no limit). LCM
    /// has no retransmission: a packet arrives only if all its ~1.5 kB IP
    /// fragments do, so on a lossy radio (e.g. 10% loss: 0.9^43 = 1% of 60 kB
    /// packets arrive, 0.9^8 = 43% of 12 kB ones) smaller packets carry more.
    int64_t max_packet_bytes = 0;
    /// The interval keyframes are due at (s; AirFrontend sets it from
    /// keyframes.period_s). The token bucket then holds one interval's share
    /// of the budget (at least the smallest packet), so keyframes at that
    /// interval share the budget evenly instead of the first after a pause
    /// taking a whole window and the next ones waiting. 0: one window.
    double keyframe_interval_s = 0.0;

    template <class V>
    void VisitFields(V& v) {
      v("budget_mbps", budget_mbps);
      v("max_keypoints", max_keypoints);
      v("min_keypoints", min_keypoints);
      v("encodings", encodings);
      v("window_s", window_s);
      v("max_packet_bytes", max_packet_bytes);
    }
    void Check() const;
  };

  /// Link bytes of a keyframe packet with `keypoints` keypoints whose local
  /// descriptors use `encoding`. Must be exact (the governor trusts it).
  using PacketBytesFn = std::function<int64_t(int keypoints, ArrayEncoding encoding)>;

  struct Plan {
    bool send = false;  ///< false: skip this keyframe (rate lowered)
    int keypoints = 0;  ///< how many of the best keypoints to send
    ArrayEncoding encoding = ArrayEncoding::kFloat32;
    int64_t bytes = 0;    ///< predicted link bytes
    std::string gave_up;  ///< human-readable, empty when nothing was given up
  };

  BandwidthGovernor(const Options& options, PacketBytesFn packet_bytes);

  /// The richest packet for a keyframe at t_ns with `available_keypoints`
  /// extracted (sorted best first) that fits the budget now.
  Plan PlanKeyframe(int64_t t_ns, int available_keypoints);

  /// Records bytes actually put on the link at t_ns (keyframes and any other
  /// message, e.g. camera info). Returns false, recording nothing, if they
  /// would break the window budget: the caller must then not send.
  bool TryConsume(int64_t t_ns, int64_t bytes);

  /// Keyframe plans leave this many bytes of every window free, for small
  /// messages the link must always carry (camera info: without it the
  /// ground can use no keyframe at all).
  void SetReserve(int64_t bytes) {
    reserve_bytes_ = bytes;
    bucket_depth_ = -1.0;  // holds the reserve too
  }

  /// Bytes sent in the trailing window ending at t_ns.
  int64_t BytesInWindow(int64_t t_ns);

  /// Budget in bytes per window; 0 when unlimited.
  int64_t window_budget_bytes() const { return window_budget_bytes_; }
  const std::vector<ArrayEncoding>& encodings() const { return encodings_; }
  int64_t keyframes_skipped() const { return keyframes_skipped_; }

 private:
  bool Fits(int64_t t_ns, int64_t bytes);
  void Refill(int64_t t_ns);
  /// Most tokens the bucket holds (bytes).
  double BucketDepth();

  Options options_;
  PacketBytesFn packet_bytes_;
  std::vector<ArrayEncoding> encodings_;
  int64_t window_ns_ = 0;
  int64_t window_budget_bytes_ = 0;
  double tokens_ = 0.0;
  double bucket_depth_ = -1.0;  ///< computed on first use (needs packet_bytes_)
  int64_t reserve_bytes_ = 0;
  int64_t last_refill_ns_ = 0;
  bool started_ = false;
  std::deque<std::pair<int64_t, int64_t>> sent_;  ///< (t_ns, bytes) in the window
  int64_t bytes_in_window_ = 0;
  int64_t keyframes_skipped_ = 0;
};

}  // namespace ag
