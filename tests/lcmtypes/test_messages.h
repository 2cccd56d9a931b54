#pragma once

// Messages with non-trivial values in every field (negative numbers, large
// timestamps, non-empty optional parts), shared by the lcmtypes tests.

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "lcmtypes/aglcm/air_keyframe_t.hpp"
#include "lcmtypes/aglcm/camera_info_t.hpp"
#include "lcmtypes/aglcm/image_t.hpp"
#include "lcmtypes/aglcm/odometry_t.hpp"
#include "lcmtypes/aglcm/point_cloud_t.hpp"
#include "lcmtypes/aglcm/quantized_array_t.hpp"
#include "lcmtypes/aglcm/relative_pose_t.hpp"

namespace ag::test {

/// Bytes of quantized_array_t.data for a layout, as documented in
/// lcmtypes/quantized_array_t.lcm.
inline int64_t QuantizedDataBytes(int encoding, int64_t count, int64_t dim, int bits) {
  using Q = aglcm::quantized_array_t;
  switch (encoding) {
    case Q::FLOAT32:
      return count * dim * 4;
    case Q::FLOAT16:
      return count * dim * 2;
    case Q::INT8:
      return count * dim;
    case Q::BITS:
      return (count * dim * bits + 7) / 8;
  }
  return -1;
}

/// A quantized_array_t whose sizes follow the documented layout; the bytes are
/// pseudo-random (their meaning is the codec's business, not the schema's).
/// `per_vector`: one scale (and for BITS one offset) per vector, else one.
inline aglcm::quantized_array_t MakeQuantized(int8_t encoding, int count, int dim, int bits,
                                              bool per_vector, uint32_t seed) {
  using Q = aglcm::quantized_array_t;
  std::mt19937 rng(seed);
  Q q;
  q.encoding = encoding;
  q.count = count;
  q.dim = dim;
  q.bits = static_cast<int8_t>(bits);
  const int num_params = per_vector ? count : 1;
  if (encoding == Q::INT8 || encoding == Q::BITS) {
    for (int i = 0; i < num_params; ++i) q.scales.push_back(0.001f * (1 + rng() % 1000));
  }
  if (encoding == Q::BITS) {
    for (int i = 0; i < num_params; ++i) q.offsets.push_back(-0.5f + 0.001f * (rng() % 500));
  }
  q.num_scales = static_cast<int32_t>(q.scales.size());
  q.num_offsets = static_cast<int32_t>(q.offsets.size());
  q.data.resize(QuantizedDataBytes(encoding, count, dim, bits));
  for (auto& b : q.data) b = static_cast<uint8_t>(rng());
  q.num_bytes = static_cast<int32_t>(q.data.size());
  return q;
}

/// An air keyframe with `num_keypoints` keypoints and scores, 4-bit 64-D
/// local descriptors and an int8 512-D global descriptor.
inline aglcm::air_keyframe_t MakeAirKeyframe(int num_keypoints, uint32_t seed = 1) {
  using Q = aglcm::quantized_array_t;
  std::mt19937 rng(seed);
  aglcm::air_keyframe_t kf;
  kf.agent = "uav_1";
  kf.seq = 4242;
  kf.part = 2;
  kf.num_parts = 3;
  kf.t_ns = 1700000000123456789;
  kf.camera_id = "cam0";
  kf.position[0] = 1.5;
  kf.position[1] = -2.25;
  kf.position[2] = 10.125;
  kf.orientation[0] = 0.5;
  kf.orientation[1] = -0.5;
  kf.orientation[2] = 0.5;
  kf.orientation[3] = -0.5;
  kf.descriptor_type = "xfeat";
  kf.global_descriptor = MakeQuantized(Q::INT8, 1, 512, 8, false, seed + 1);
  kf.num_keypoints = num_keypoints;
  kf.keypoint_frac_bits = 3;
  for (int i = 0; i < num_keypoints; ++i) {
    kf.kp_x.push_back(static_cast<int16_t>(rng() % 5120));  // < 640 px at 1/8 px
    kf.kp_y.push_back(static_cast<int16_t>(rng() % 3840));  // < 480 px
    kf.scores.push_back(static_cast<uint8_t>(rng()));
  }
  kf.num_scores = num_keypoints;
  kf.descriptors = MakeQuantized(Q::BITS, num_keypoints, 64, 4, true, seed + 2);
  return kf;
}

inline aglcm::camera_info_t MakeCameraInfo() {
  aglcm::camera_info_t c;
  c.agent = "uav_1";
  c.camera_id = "cam0";
  c.t_ns = 1700000000500000000;
  c.model = "equidistant";
  c.width = 752;
  c.height = 480;
  c.intrinsics[0] = 458.654;
  c.intrinsics[1] = 457.296;
  c.intrinsics[2] = 367.215;
  c.intrinsics[3] = 248.375;
  c.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  c.num_distortion = static_cast<int32_t>(c.distortion.size());
  c.has_T_body_camera = 1;
  for (int r = 0; r < 4; ++r) {
    for (int col = 0; col < 4; ++col) c.T_body_camera[r][col] = 0.1 * (4 * r + col) - 0.7;
  }
  c.time_offset_s = -0.0021;
  return c;
}

inline aglcm::relative_pose_t MakeRelativePose() {
  aglcm::relative_pose_t p;
  p.agent = "uav_1";
  p.ground_agent = "ugv";
  p.seq = 77;
  p.t_ns = 1700000100000000000;
  p.air_t_ns = 1600000099900000000;
  p.air_seq = 4242;
  p.status = aglcm::relative_pose_t::TRACKING;
  p.status_reason = "tracking: 143 inliers";
  p.x = 12.5;
  p.y = -3.75;
  p.z = 0.625;
  p.yaw = -2.1;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      p.T_wa_wg[r][c] = 1.0 + r - 0.5 * c;
      p.covariance[r][c] = 1e-4 * (1 + r + c);
    }
  }
  p.num_inliers = 143;
  p.num_keyframe_pairs = 6;
  p.rms_reprojection_error_px = 0.83f;
  p.latency_s = 0.045f;
  p.solve_time_s = 0.031f;
  return p;
}

inline aglcm::image_t MakeImage() {
  aglcm::image_t im;
  im.t_ns = 1700000000033333333;
  im.frame_id = "cam_front";
  im.width = 5;
  im.height = 3;
  im.encoding = "bgr8";
  im.step = 16;  // 15 bytes of pixels + 1 byte of row padding
  im.data.resize(im.step * im.height);
  for (size_t i = 0; i < im.data.size(); ++i) im.data[i] = static_cast<uint8_t>(255 - 7 * i);
  im.num_bytes = static_cast<int32_t>(im.data.size());
  return im;
}

inline aglcm::odometry_t MakeOdometry() {
  aglcm::odometry_t o;
  o.t_ns = 1700000000010000000;
  o.world_frame_id = "wg";
  o.body_frame_id = "body";
  const double position[3] = {101.25, -55.5, 0.375};
  const double orientation[4] = {0.9238795325112867, 0.0, 0.0, 0.3826834323650898};
  for (int i = 0; i < 3; ++i) o.position[i] = position[i];
  for (int i = 0; i < 4; ++i) o.orientation[i] = orientation[i];
  o.has_twist = 1;
  for (int i = 0; i < 3; ++i) {
    o.linear_velocity[i] = 1.5 - i;
    o.angular_velocity[i] = -0.25 * (i + 1);
  }
  o.has_pose_covariance = 1;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) o.pose_covariance[r][c] = (r == c ? 1e-3 : 1e-5) * (1 + r * c);
  }
  return o;
}

inline aglcm::point_cloud_t MakePointCloud(int num_points = 100) {
  aglcm::point_cloud_t pc;
  pc.t_ns = 1700000000100000000;
  pc.frame_id = "lidar";
  pc.num_points = num_points;
  for (int i = 0; i < num_points; ++i) {
    pc.x.push_back(0.5f * i - 20.0f);
    pc.y.push_back(-0.25f * i);
    pc.z.push_back(0.01f * (i % 37) - 1.0f);
    pc.intensity.push_back(static_cast<float>(i % 256));
  }
  pc.num_intensities = num_points;
  return pc;
}

/// The LCM encoding of `msg` (fingerprint included), as published.
template <class Msg>
std::vector<uint8_t> Encode(const Msg& msg) {
  std::vector<uint8_t> buf(msg.getEncodedSize());
  const int n = msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
  buf.resize(n < 0 ? 0 : n);
  return buf;
}

}  // namespace ag::test
