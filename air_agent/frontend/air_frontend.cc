#include "air_agent/frontend/air_frontend.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "common/core/agent_name.h"
#include "common/wire/channels.h"

namespace ag {

void AirFrontend::Options::Check() const {
  CheckOption(!camera_id.empty(), "camera_id", "must not be empty");
  CheckOption(ParseArrayEncoding(global_encoding).has_value(), "global_encoding",
              "must be float32, float16, int8 or bits4; got '" + global_encoding + "'");
  CheckOption(mtu >= 576 && mtu <= 65535, "mtu", "must be in [576, 65535]");
  CheckOption(camera_info_period_s > 0, "camera_info_period_s", "must be > 0");
  CheckOption(max_part_bytes >= 0, "max_part_bytes", "must be >= 0 (0: keyframes are not split)");
}

namespace {

/// The governor's options, its bucket sized for keyframes at the selector's period.
BandwidthGovernor::Options GovernorOptions(const AirFrontend::Options& options) {
  BandwidthGovernor::Options g = options.governor;
  g.keyframe_interval_s = options.keyframes.period_s;
  return g;
}

}  // namespace

AirFrontend::AirFrontend(std::string agent, const Options& options,
                         const CameraCalibration& calibration, const FeatureExtractor* features,
                         const GlobalDescriptorExtractor* global)
    : agent_(std::move(agent)),
      channel_(AirKeyframeChannel(agent_)),
      options_(options),
      calibration_(calibration),
      features_(features),
      global_(global),
      selector_(options.keyframes),
      governor_(GovernorOptions(options),
                [this](int keypoints, ArrayEncoding encoding) {
                  return KeyframeLinkBytes(keypoints, encoding);
                }),
      global_encoding_(
          ParseArrayEncoding(options.global_encoding).value_or(ArrayEncoding::kFloat16)) {
  options_.Check();
  if (!IsValidAgentName(agent_)) {
    throw OptionError("agent", "'" + agent_ + "' is not a valid agent name ([a-z0-9_]+)");
  }
  Camera check(calibration.camera);  // throws naming the bad field
  if (options_.max_part_bytes > 0) {
    const auto fits = [this](int64_t size) {
      return LcmLinkBytes(channel_, size, options_.mtu).ip <= options_.max_part_bytes;
    };
    for (ArrayEncoding e : governor_.encodings()) {
      try {
        part_capacity_[e] = FitPartCapacity(agent_, options_.camera_id, features_->type(),
                                            features_->descriptor_dim(), global_->dim(),
                                            Format(0, e), options_.governor.max_keypoints, fits);
      } catch (const std::invalid_argument& error) {
        throw OptionError("max_part_bytes", std::to_string(options_.max_part_bytes) +
                                                " IPv4 bytes is too small: " + error.what());
      }
    }
  }
  governor_.SetReserve(
      LcmLinkBytes(AirCameraInfoChannel(agent_), CameraInfo(0).getEncodedSize(), options_.mtu).ip);
}

PacketFormat AirFrontend::Format(int keypoints, ArrayEncoding descriptors) const {
  PacketFormat f;
  f.max_keypoints = keypoints;
  f.descriptors = descriptors;
  f.global = global_encoding_;
  f.scores = options_.send_scores;
  return f;
}

int64_t AirFrontend::KeyframeLinkBytes(int keypoints, ArrayEncoding descriptors) const {
  const PacketFormat f = Format(keypoints, descriptors);
  if (options_.max_part_bytes == 0) {
    const int64_t size =
        EncodedKeyframeSize(agent_, options_.camera_id, features_->type(), keypoints,
                            features_->descriptor_dim(), global_->dim(), f);
    return LcmLinkBytes(channel_, size, options_.mtu).ip;
  }
  int64_t ip = 0;
  for (int64_t size : EncodedPartSizes(agent_, options_.camera_id, features_->type(), keypoints,
                                       features_->descriptor_dim(), global_->dim(), f,
                                       part_capacity_.at(descriptors))) {
    ip += LcmLinkBytes(channel_, size, options_.mtu).ip;
  }
  return ip;
}

int64_t AirFrontend::BodyTimeNs(int64_t t_camera_ns) const {
  return t_camera_ns + static_cast<int64_t>(std::llround(calibration_.time_offset_s * 1e9));
}

AirFrontend::Output AirFrontend::ProcessFrame(int64_t t_camera_ns,
                                              const std::function<cv::Mat()>& load_image,
                                              const Pose& T_wa_body) {
  Output out;
  const Pose T_wa_c = T_wa_body * calibration_.T_body_camera;
  if (!selector_.Consider(t_camera_ns, T_wa_c).is_keyframe) return out;

  const cv::Mat image = load_image();
  const auto start = std::chrono::steady_clock::now();
  AirKeyframe kf;
  kf.agent = agent_;
  kf.seq = seq_;
  kf.t_ns = t_camera_ns;
  kf.camera_id = options_.camera_id;
  kf.T_wa_c = T_wa_c;
  kf.features = features_->Extract(image);
  kf.global_descriptor = global_->Compute(image, kf.features);
  out.features_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();

  const BandwidthGovernor::Plan plan =
      governor_.PlanKeyframe(t_camera_ns, static_cast<int>(kf.features.size()));
  out.gave_up = plan.gave_up;
  if (!plan.send) {
    selector_.Reject();  // try again with the next frame
    out.skipped = true;
    return out;
  }
  const PacketFormat format = Format(plan.keypoints, plan.encoding);
  if (options_.max_part_bytes > 0) {
    out.packets = EncodeKeyframeParts(kf, format, part_capacity_.at(plan.encoding));
  } else {
    out.packets = {EncodeKeyframe(kf, format)};
  }
  for (const aglcm::air_keyframe_t& p : out.packets) {
    const int64_t size = p.getEncodedSize();
    const LinkBytes b = LcmLinkBytes(channel_, size, options_.mtu);
    out.keypoints += p.num_keypoints;
    out.encoded_bytes += size;
    out.link.payload += b.payload;
    out.link.lcm_udp += b.lcm_udp;
    out.link.datagrams += b.datagrams;
    out.link.ip += b.ip;
    out.link.ip_packets += b.ip_packets;
  }
  if (!governor_.TryConsume(t_camera_ns, out.link.ip)) {
    // The plan's size model and the packet disagree: never exceed the budget.
    selector_.Reject();
    out.skipped = true;
    out.gave_up = "packet of " + std::to_string(out.link.ip) + " bytes does not fit the budget";
    return out;
  }
  out.keyframe = true;
  ++seq_;
  return out;
}

aglcm::camera_info_t AirFrontend::CameraInfo(int64_t t_ns) const {
  aglcm::camera_info_t info;
  const CameraParams& p = calibration_.camera;
  info.agent = agent_;
  info.camera_id = options_.camera_id;
  info.t_ns = t_ns;
  info.model = p.model;
  info.width = p.width;
  info.height = p.height;
  info.intrinsics[0] = p.fx;
  info.intrinsics[1] = p.fy;
  info.intrinsics[2] = p.cx;
  info.intrinsics[3] = p.cy;
  info.num_distortion = static_cast<int32_t>(p.distortion.size());
  info.distortion = p.distortion;
  info.has_T_body_camera = true;
  const Eigen::Matrix4d T = calibration_.T_body_camera.matrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) info.T_body_camera[r][c] = T(r, c);
  }
  info.time_offset_s = calibration_.time_offset_s;
  return info;
}

bool AirFrontend::CameraInfoDue(int64_t t_ns) {
  if (last_camera_info_ns_ &&
      1e-9 * static_cast<double>(t_ns - *last_camera_info_ns_) < options_.camera_info_period_s) {
    return false;
  }
  const int64_t bytes =
      LcmLinkBytes(AirCameraInfoChannel(agent_), CameraInfo(t_ns).getEncodedSize(), options_.mtu)
          .ip;
  if (!governor_.TryConsume(t_ns, bytes)) return false;
  last_camera_info_ns_ = t_ns;
  return true;
}

bool AirFrontend::ConsumeOther(int64_t t_ns, int64_t link_bytes) {
  return governor_.TryConsume(t_ns, link_bytes);
}

}  // namespace ag
