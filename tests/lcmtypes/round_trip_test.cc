// Encode/decode round trips of every aglcm message, and the decoder's
// behaviour on truncated or mistyped buffers.

#include <gtest/gtest.h>

#include <cstddef>
#include <vector>

#include "lcmtypes/checked_decode.h"
#include "tests/lcmtypes/test_messages.h"

namespace ag {
namespace {

using test::Encode;

template <class T, size_t N>
void ExpectArrayEq(const T (&a)[N], const T (&b)[N], const char* name) {
  for (size_t i = 0; i < N; ++i) EXPECT_EQ(a[i], b[i]) << name << "[" << i << "]";
}

template <class T, size_t R, size_t C>
void ExpectArrayEq(const T (&a)[R][C], const T (&b)[R][C], const char* name) {
  for (size_t r = 0; r < R; ++r) {
    for (size_t c = 0; c < C; ++c)
      EXPECT_EQ(a[r][c], b[r][c]) << name << "[" << r << "][" << c << "]";
  }
}

void ExpectEqual(const aglcm::quantized_array_t& a, const aglcm::quantized_array_t& b) {
  EXPECT_EQ(a.encoding, b.encoding);
  EXPECT_EQ(a.count, b.count);
  EXPECT_EQ(a.dim, b.dim);
  EXPECT_EQ(a.bits, b.bits);
  EXPECT_EQ(a.num_scales, b.num_scales);
  EXPECT_EQ(a.scales, b.scales);
  EXPECT_EQ(a.num_offsets, b.num_offsets);
  EXPECT_EQ(a.offsets, b.offsets);
  EXPECT_EQ(a.num_bytes, b.num_bytes);
  EXPECT_EQ(a.data, b.data);
}

void ExpectEqual(const aglcm::air_keyframe_t& a, const aglcm::air_keyframe_t& b) {
  EXPECT_EQ(a.agent, b.agent);
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.part, b.part);
  EXPECT_EQ(a.num_parts, b.num_parts);
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.camera_id, b.camera_id);
  ExpectArrayEq(a.position, b.position, "position");
  ExpectArrayEq(a.orientation, b.orientation, "orientation");
  EXPECT_EQ(a.descriptor_type, b.descriptor_type);
  ExpectEqual(a.global_descriptor, b.global_descriptor);
  EXPECT_EQ(a.num_keypoints, b.num_keypoints);
  EXPECT_EQ(a.keypoint_frac_bits, b.keypoint_frac_bits);
  EXPECT_EQ(a.kp_x, b.kp_x);
  EXPECT_EQ(a.kp_y, b.kp_y);
  EXPECT_EQ(a.num_scores, b.num_scores);
  EXPECT_EQ(a.scores, b.scores);
  ExpectEqual(a.descriptors, b.descriptors);
}

void ExpectEqual(const aglcm::camera_info_t& a, const aglcm::camera_info_t& b) {
  EXPECT_EQ(a.agent, b.agent);
  EXPECT_EQ(a.camera_id, b.camera_id);
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.model, b.model);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  ExpectArrayEq(a.intrinsics, b.intrinsics, "intrinsics");
  EXPECT_EQ(a.num_distortion, b.num_distortion);
  EXPECT_EQ(a.distortion, b.distortion);
  EXPECT_EQ(a.has_T_body_camera, b.has_T_body_camera);
  ExpectArrayEq(a.T_body_camera, b.T_body_camera, "T_body_camera");
  EXPECT_EQ(a.time_offset_s, b.time_offset_s);
}

void ExpectEqual(const aglcm::relative_pose_t& a, const aglcm::relative_pose_t& b) {
  EXPECT_EQ(a.agent, b.agent);
  EXPECT_EQ(a.ground_agent, b.ground_agent);
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.air_t_ns, b.air_t_ns);
  EXPECT_EQ(a.air_seq, b.air_seq);
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.status_reason, b.status_reason);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.z, b.z);
  EXPECT_EQ(a.yaw, b.yaw);
  ExpectArrayEq(a.T_wa_wg, b.T_wa_wg, "T_wa_wg");
  ExpectArrayEq(a.covariance, b.covariance, "covariance");
  EXPECT_EQ(a.num_inliers, b.num_inliers);
  EXPECT_EQ(a.num_keyframe_pairs, b.num_keyframe_pairs);
  EXPECT_EQ(a.rms_reprojection_error_px, b.rms_reprojection_error_px);
  EXPECT_EQ(a.latency_s, b.latency_s);
  EXPECT_EQ(a.solve_time_s, b.solve_time_s);
}

void ExpectEqual(const aglcm::image_t& a, const aglcm::image_t& b) {
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.frame_id, b.frame_id);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.encoding, b.encoding);
  EXPECT_EQ(a.step, b.step);
  EXPECT_EQ(a.num_bytes, b.num_bytes);
  EXPECT_EQ(a.data, b.data);
}

void ExpectEqual(const aglcm::odometry_t& a, const aglcm::odometry_t& b) {
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.world_frame_id, b.world_frame_id);
  EXPECT_EQ(a.body_frame_id, b.body_frame_id);
  ExpectArrayEq(a.position, b.position, "position");
  ExpectArrayEq(a.orientation, b.orientation, "orientation");
  EXPECT_EQ(a.has_twist, b.has_twist);
  ExpectArrayEq(a.linear_velocity, b.linear_velocity, "linear_velocity");
  ExpectArrayEq(a.angular_velocity, b.angular_velocity, "angular_velocity");
  EXPECT_EQ(a.has_pose_covariance, b.has_pose_covariance);
  ExpectArrayEq(a.pose_covariance, b.pose_covariance, "pose_covariance");
}

void ExpectEqual(const aglcm::point_cloud_t& a, const aglcm::point_cloud_t& b) {
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.frame_id, b.frame_id);
  EXPECT_EQ(a.num_points, b.num_points);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.z, b.z);
  EXPECT_EQ(a.num_intensities, b.num_intensities);
  EXPECT_EQ(a.intensity, b.intensity);
}

/// Encodes, decodes with both the generated decode() and DecodeChecked(),
/// compares every field, and checks that re-encoding gives the same bytes.
template <class Msg>
void ExpectRoundTrip(const Msg& sent) {
  const std::vector<uint8_t> buf = Encode(sent);
  ASSERT_EQ(static_cast<int>(buf.size()), sent.getEncodedSize());
  ASSERT_GT(buf.size(), 8u);

  Msg plain;
  ASSERT_EQ(plain.decode(buf.data(), 0, static_cast<int>(buf.size())), sent.getEncodedSize());
  ExpectEqual(sent, plain);

  Msg checked;
  ASSERT_EQ(DecodeChecked(buf.data(), static_cast<int>(buf.size()), &checked),
            sent.getEncodedSize());
  ExpectEqual(sent, checked);
  EXPECT_EQ(Encode(checked), buf);
}

TEST(LcmRoundTrip, QuantizedArrayInEveryEncoding) {
  using Q = aglcm::quantized_array_t;
  // quantized_array_t is only sent nested, but it is a message of its own too.
  ExpectRoundTrip(test::MakeQuantized(Q::FLOAT32, 3, 7, 32, false, 1));
  ExpectRoundTrip(test::MakeQuantized(Q::FLOAT16, 5, 9, 16, false, 2));
  ExpectRoundTrip(test::MakeQuantized(Q::INT8, 4, 6, 8, true, 3));
  ExpectRoundTrip(test::MakeQuantized(Q::INT8, 4, 6, 8, false, 4));
  ExpectRoundTrip(test::MakeQuantized(Q::BITS, 11, 13, 3, true, 5));
  ExpectRoundTrip(test::MakeQuantized(Q::BITS, 2, 64, 1, false, 6));
}

TEST(LcmRoundTrip, AirKeyframe) {
  ExpectRoundTrip(test::MakeAirKeyframe(300));
  ExpectRoundTrip(test::MakeAirKeyframe(0));  // no keypoints is a valid keyframe
}

TEST(LcmRoundTrip, AirKeyframeWithoutScoresAndFloatDescriptors) {
  using Q = aglcm::quantized_array_t;
  aglcm::air_keyframe_t kf = test::MakeAirKeyframe(50, 9);
  kf.scores.clear();
  kf.num_scores = 0;
  kf.descriptors = test::MakeQuantized(Q::FLOAT16, 50, 128, 16, false, 10);
  kf.global_descriptor = test::MakeQuantized(Q::FLOAT32, 1, 512, 32, false, 11);
  kf.descriptor_type = "sift";
  ExpectRoundTrip(kf);
}

TEST(LcmRoundTrip, CameraInfo) { ExpectRoundTrip(test::MakeCameraInfo()); }

TEST(LcmRoundTrip, RelativePose) { ExpectRoundTrip(test::MakeRelativePose()); }

TEST(LcmRoundTrip, Image) { ExpectRoundTrip(test::MakeImage()); }

TEST(LcmRoundTrip, Odometry) { ExpectRoundTrip(test::MakeOdometry()); }

TEST(LcmRoundTrip, PointCloud) { ExpectRoundTrip(test::MakePointCloud()); }

TEST(LcmConstants, MatchTheDocumentedValues) {
  // Enum values are part of the wire format: a renumbering would make old
  // and new agents misread each other without any fingerprint change.
  EXPECT_EQ(aglcm::quantized_array_t::FLOAT32, 0);
  EXPECT_EQ(aglcm::quantized_array_t::FLOAT16, 1);
  EXPECT_EQ(aglcm::quantized_array_t::INT8, 2);
  EXPECT_EQ(aglcm::quantized_array_t::BITS, 3);
  EXPECT_EQ(aglcm::relative_pose_t::INITIALIZING, 0);
  EXPECT_EQ(aglcm::relative_pose_t::TRACKING, 1);
  EXPECT_EQ(aglcm::relative_pose_t::LOST, 2);
}

/// Every strict prefix of a valid buffer must be rejected by both decoders.
template <class Msg>
void ExpectEveryTruncationRejected(const Msg& sent) {
  const std::vector<uint8_t> buf = Encode(sent);
  for (size_t len = 0; len < buf.size(); ++len) {
    // A copy of exactly `len` bytes, so reading past it is caught by ASan.
    const std::vector<uint8_t> prefix(buf.begin(), buf.begin() + len);
    Msg plain;
    EXPECT_LT(plain.decode(prefix.data(), 0, static_cast<int>(len)), 0) << "length " << len;
    Msg checked;
    EXPECT_LT(DecodeChecked(prefix.data(), static_cast<int>(len), &checked), 0) << "length " << len;
  }
}

TEST(LcmDecode, RejectsEveryTruncation) {
  ExpectEveryTruncationRejected(test::MakeAirKeyframe(20));
  ExpectEveryTruncationRejected(test::MakeCameraInfo());
  ExpectEveryTruncationRejected(test::MakeRelativePose());
  ExpectEveryTruncationRejected(test::MakeImage());
  ExpectEveryTruncationRejected(test::MakeOdometry());
  ExpectEveryTruncationRejected(test::MakePointCloud(10));
}

TEST(LcmDecode, RejectsACorruptedFingerprint) {
  std::vector<uint8_t> buf = Encode(test::MakeAirKeyframe(20));
  for (int byte = 0; byte < 8; ++byte) {
    std::vector<uint8_t> bad = buf;
    bad[byte] ^= 0x10;
    aglcm::air_keyframe_t plain;
    EXPECT_LT(plain.decode(bad.data(), 0, static_cast<int>(bad.size())), 0);
    aglcm::air_keyframe_t checked;
    EXPECT_LT(DecodeChecked(bad.data(), static_cast<int>(bad.size()), &checked), 0);
  }
}

TEST(LcmDecode, RejectsAnotherMessageType) {
  // The fingerprint is what keeps a receiver from reading one message as
  // another on a mis-wired channel.
  const std::vector<uint8_t> pose = Encode(test::MakeRelativePose());
  aglcm::air_keyframe_t kf;
  EXPECT_LT(kf.decode(pose.data(), 0, static_cast<int>(pose.size())), 0);
  EXPECT_LT(DecodeChecked(pose.data(), static_cast<int>(pose.size()), &kf), 0);
  const std::vector<uint8_t> odom = Encode(test::MakeOdometry());
  aglcm::relative_pose_t rp;
  EXPECT_LT(rp.decode(odom.data(), 0, static_cast<int>(odom.size())), 0);
  EXPECT_LT(DecodeChecked(odom.data(), static_cast<int>(odom.size()), &rp), 0);
}

TEST(LcmDecode, FingerprintsDifferBetweenMessages) {
  const std::vector<int64_t> hashes = {
      aglcm::quantized_array_t::getHash(), aglcm::air_keyframe_t::getHash(),
      aglcm::camera_info_t::getHash(),     aglcm::relative_pose_t::getHash(),
      aglcm::image_t::getHash(),           aglcm::odometry_t::getHash(),
      aglcm::point_cloud_t::getHash()};
  for (size_t i = 0; i < hashes.size(); ++i) {
    for (size_t j = i + 1; j < hashes.size(); ++j) EXPECT_NE(hashes[i], hashes[j]) << i << " " << j;
  }
}

}  // namespace
}  // namespace ag
