#pragma once

// What the UAV does with each camera frame: keyframe selection, features,
// global descriptor, bandwidth governor, packet. Callable without threads or
// LCM (the daemon publishes what this returns; the evaluator decodes it).

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "air_agent/governor/bandwidth_governor.h"
#include "air_agent/keyframe/keyframe_selector.h"
#include "common/camera/camera.h"
#include "common/dataset/dataset.h"
#include "common/features/feature_extractor.h"
#include "common/features/global_descriptor.h"
#include "common/wire/keyframe_codec.h"
#include "common/wire/link_bytes.h"
#include "lcmtypes/aglcm/camera_info_t.hpp"

namespace ag {

class AirFrontend {
 public:
  struct Options {
    std::string camera_id = "cam0";           ///< names the camera_info of this camera
    KeyframeSelector::Options keyframes;      ///< when to send
    BandwidthGovernor::Options governor;      ///< how much to send
    std::string global_encoding = "float16";  ///< float32, float16, int8, bits4
    bool send_scores = false;                 ///< 1 byte per keypoint more
    int mtu = 1500;                           ///< for the link byte count (bytes)
    /// Split each keyframe into parts of at most this many IPv4 bytes on the
    /// link (0: one message per keyframe). At the MTU each part is one IP
    /// packet, so a packet lost on the radio costs that part's keypoints
    /// instead of the whole keyframe (air_keyframe_t.lcm).
    int64_t max_part_bytes = 0;
    /// camera_info resent this often (s): ~330 IPv4 bytes, a lost one delays every
    /// keyframe until the next arrives
    double camera_info_period_s = 1.0;

    template <class V>
    void VisitFields(V& v) {
      v("camera_id", camera_id);
      v("keyframes", keyframes);
      v("governor", governor);
      v("global_encoding", global_encoding);
      v("send_scores", send_scores);
      v("mtu", mtu);
      v("max_part_bytes", max_part_bytes);
      v("camera_info_period_s", camera_info_period_s);
    }
    void Check() const;
  };

  struct Output {
    bool keyframe = false;  ///< packets were produced
    bool skipped = false;   ///< a keyframe was due but the budget had no room
    /// The keyframe's messages, to publish in order: one, or its parts.
    std::vector<aglcm::air_keyframe_t> packets;
    int keypoints = 0;          ///< keypoints sent, all parts together
    int64_t encoded_bytes = 0;  ///< LCM message sizes, summed over the packets
    LinkBytes link;             ///< what they cost on the link, summed
    std::string gave_up;        ///< what the governor gave up, if anything
    double features_ms = 0;     ///< local + global descriptor time
  };

  /// `agent` names the UAV ([a-z0-9_]+). The extractors must outlive this.
  AirFrontend(std::string agent, const Options& options, const CameraCalibration& calibration,
              const FeatureExtractor* features, const GlobalDescriptorExtractor* global);
  AirFrontend(const AirFrontend&) = delete;  // the governor's size model refers to this
  AirFrontend& operator=(const AirFrontend&) = delete;

  /// One camera frame at t_camera_ns (air clock) with the VIO body pose at
  /// the matching body time (t_camera + time_offset). Frames in time order.
  /// `load_image` is called only when the frame becomes a keyframe.
  Output ProcessFrame(int64_t t_camera_ns, const std::function<cv::Mat()>& load_image,
                      const Pose& T_wa_body);
  Output ProcessFrame(int64_t t_camera_ns, const cv::Mat& image, const Pose& T_wa_body) {
    return ProcessFrame(
        t_camera_ns, [&image] { return image; }, T_wa_body);
  }

  /// The camera_info message of this camera at t_ns.
  aglcm::camera_info_t CameraInfo(int64_t t_ns) const;
  /// True when camera_info is due at t_ns (first call, then every
  /// camera_info_period_s) and fits the budget; its bytes are then counted.
  bool CameraInfoDue(int64_t t_ns);
  /// Records other traffic (camera info) in the governor's window; false when
  /// it does not fit now (then do not send it).
  bool ConsumeOther(int64_t t_ns, int64_t link_bytes);

  const std::string& agent() const { return agent_; }
  const std::string& channel() const { return channel_; }
  int64_t sequence() const { return seq_; }
  /// Body time of a camera time (t_body = t_camera + time_offset_s).
  int64_t BodyTimeNs(int64_t t_camera_ns) const;

 private:
  std::string agent_;
  std::string channel_;
  Options options_;
  CameraCalibration calibration_;
  const FeatureExtractor* features_;
  const GlobalDescriptorExtractor* global_;
  KeyframeSelector selector_;
  BandwidthGovernor governor_;
  ArrayEncoding global_encoding_;
  int64_t seq_ = 0;
  std::optional<int64_t> last_camera_info_ns_;
  /// Part capacity per descriptor encoding, when keyframes are split.
  std::map<ArrayEncoding, PartCapacity> part_capacity_;

  PacketFormat Format(int keypoints, ArrayEncoding descriptors) const;
  /// Link bytes of a keyframe with `keypoints` keypoints in `descriptors`.
  int64_t KeyframeLinkBytes(int keypoints, ArrayEncoding descriptors) const;
};

}  // namespace ag
