#include "common/wire/keyframe_assembler.h"

#include <opencv2/core.hpp>

namespace ag {
namespace {

/// Why `part` cannot belong to the keyframe whose part `first` is, or "".
std::string Disagreement(const AirKeyframe& first, const AirKeyframe& part) {
  if (part.t_ns != first.t_ns) return "t_ns";
  if (part.camera_id != first.camera_id) return "camera_id";
  if (part.features.descriptor_type != first.features.descriptor_type) return "descriptor_type";
  if (!part.T_wa_c.isApprox(first.T_wa_c, 1e-9)) return "camera pose";
  if (!part.features.descriptors.empty() && !first.features.descriptors.empty() &&
      part.features.descriptors.cols != first.features.descriptors.cols) {
    return "descriptor length";
  }
  return "";
}

}  // namespace

std::vector<KeyframeAssembler::Joined> KeyframeAssembler::Add(DecodedKeyframe part, double now_s,
                                                              std::string* error) {
  error->clear();
  const Key key{part.keyframe.agent, part.keyframe.seq};
  // Parts of one keyframe come back to back: another keyframe of this agent
  // means the pending ones will get no more parts.
  std::vector<Key> done;
  for (const auto& [k, p] : pending_) {
    if (k.first == key.first && k.second != key.second) done.push_back(k);
  }
  std::vector<Joined> out = Finish(done);
  if (part.num_parts <= 1) {
    Joined whole;
    whole.usable = true;
    whole.keyframe = std::move(part.keyframe);
    whole.parts_received = whole.num_parts = 1;
    out.push_back(std::move(whole));
    return out;
  }
  const std::string where = "keyframe part " + std::to_string(part.part) + "/" +
                            std::to_string(part.num_parts) + " of '" + key.first + "' seq " +
                            std::to_string(key.second);
  auto it = pending_.find(key);
  if (it == pending_.end()) {
    it = pending_.emplace(key, Pending{}).first;
    it->second.num_parts = part.num_parts;
  } else {
    const AirKeyframe& first = it->second.parts.begin()->second;
    std::string differs =
        part.num_parts != it->second.num_parts ? "num_parts" : Disagreement(first, part.keyframe);
    if (!differs.empty()) {
      *error = where + ": its " + differs + " differs from the earlier parts; part ignored";
      return out;
    }
    if (it->second.parts.count(part.part) > 0) {
      *error = where + ": received twice; the copy ignored";
      return out;
    }
  }
  it->second.last_s = now_s;
  it->second.parts.emplace(part.part, std::move(part.keyframe));
  if (static_cast<int>(it->second.parts.size()) == it->second.num_parts) {
    std::vector<Joined> complete = Finish({key});
    out.push_back(std::move(complete.front()));
  }
  return out;
}

std::vector<KeyframeAssembler::Joined> KeyframeAssembler::Expire(double now_s) {
  std::vector<Key> done;
  for (const auto& [k, p] : pending_) {
    if (now_s - p.last_s > timeout_s_) done.push_back(k);
  }
  return Finish(done);
}

std::vector<KeyframeAssembler::Joined> KeyframeAssembler::Finish(const std::vector<Key>& keys) {
  std::vector<Joined> out;
  for (const Key& k : keys) {
    auto it = pending_.find(k);
    if (it == pending_.end()) continue;
    out.push_back(Join(std::move(it->second)));
    pending_.erase(it);
  }
  return out;
}

KeyframeAssembler::Joined KeyframeAssembler::Join(Pending&& pending) {
  Joined j;
  j.num_parts = pending.num_parts;
  j.parts_received = static_cast<int>(pending.parts.size());
  AirKeyframe& kf = j.keyframe;
  kf = std::move(pending.parts.begin()->second);
  // The first and the last part carry the global descriptor.
  const AirKeyframe& last = std::prev(pending.parts.end())->second;
  if (kf.global_descriptor.empty() && pending.parts.size() > 1) {
    kf.global_descriptor = last.global_descriptor;
  }
  j.usable = !kf.global_descriptor.empty();
  bool all_scored = kf.features.scores.size() == kf.features.size();
  std::vector<cv::Mat> descriptors;
  if (!kf.features.descriptors.empty()) descriptors.push_back(kf.features.descriptors);
  for (auto it = std::next(pending.parts.begin()); it != pending.parts.end(); ++it) {
    LocalFeatures& f = it->second.features;
    kf.features.keypoints.insert(kf.features.keypoints.end(), f.keypoints.begin(),
                                 f.keypoints.end());
    all_scored = all_scored && f.scores.size() == f.size();
    kf.features.scores.insert(kf.features.scores.end(), f.scores.begin(), f.scores.end());
    if (!f.descriptors.empty()) descriptors.push_back(f.descriptors);
  }
  // Scores only when every part had them (they line up with the keypoints).
  if (!all_scored) kf.features.scores.clear();
  if (descriptors.size() > 1) cv::vconcat(descriptors, kf.features.descriptors);
  return j;
}

}  // namespace ag
