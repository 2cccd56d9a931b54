#pragma once

// Joins the parts of split air keyframes (air_keyframe_t.num_parts > 1) back
// into keyframes, keeping what arrived when some parts were lost on the link.

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/types/keyframe.h"
#include "common/wire/keyframe_codec.h"

namespace ag {

/// air_agent sends the parts of a keyframe back to back, so a keyframe is
/// final when all its parts are in, when a part of another keyframe of the
/// same agent arrives (its missing parts are lost), or `timeout_s` after its
/// latest part. A keyframe that lost both parts with the global descriptor
/// (the first and the last) could never be retrieved: it comes back unusable. Times are any
/// monotonic clock, in seconds (the server's wall clock, the evaluator's data time).
class KeyframeAssembler {
 public:
  struct Joined {
    bool usable = false;   ///< false: no global descriptor arrived (first and last part lost)
    AirKeyframe keyframe;  ///< the keypoints of every part received, in part order
    int parts_received = 0;
    int num_parts = 1;
  };

  explicit KeyframeAssembler(double timeout_s = 0.5) : timeout_s_(timeout_s) {}

  /// Adds one decoded packet received at `now_s`; returns the keyframes that
  /// are now final (a whole keyframe, num_parts 1, comes straight back).
  /// A part that contradicts the earlier parts of its keyframe (a different
  /// part count, time, camera, pose, descriptor type or size) or repeats one
  /// is not used: `error` then says why (it is empty otherwise).
  std::vector<Joined> Add(DecodedKeyframe part, double now_s, std::string* error);

  /// Keyframes whose latest part arrived more than timeout_s before `now_s`.
  std::vector<Joined> Expire(double now_s);

  size_t pending() const { return pending_.size(); }

 private:
  struct Pending {
    int num_parts = 1;
    double last_s = 0;
    std::map<int, AirKeyframe> parts;  ///< by part index
  };
  using Key = std::pair<std::string, int64_t>;  ///< agent, seq

  static Joined Join(Pending&& pending);
  std::vector<Joined> Finish(const std::vector<Key>& keys);

  double timeout_s_;
  std::map<Key, Pending> pending_;
};

}  // namespace ag
