#include "common/wire/keyframe_codec.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <random>

namespace ag {
namespace {

AirKeyframe MakeKeyframe(int n, int dim, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  std::normal_distribution<float> g(0, 1);
  AirKeyframe kf;
  kf.agent = "uav_1";
  kf.seq = 42;
  kf.t_ns = 1700000000123456789LL;
  kf.camera_id = "cam0";
  kf.T_wa_c =
      MakePose4Dof(1.5, -2.25, 8.0, 0.3) * Pose(Eigen::AngleAxisd(0.9, Eigen::Vector3d::UnitX()));
  kf.features.descriptor_type = "xfeat";
  kf.features.descriptors = cv::Mat(n, dim, CV_32F);
  for (int i = 0; i < n; ++i) {
    kf.features.keypoints.emplace_back(639.0f * u(rng), 479.0f * u(rng));
    kf.features.scores.push_back(1.0f - static_cast<float>(i) / n);
    for (int j = 0; j < dim; ++j) kf.features.descriptors.at<float>(i, j) = g(rng);
    cv::Mat row = kf.features.descriptors.row(i);
    cv::normalize(row, row);
  }
  kf.global_descriptor.resize(512);
  double norm = 0;
  for (float& v : kf.global_descriptor) {
    v = g(rng);
    norm += v * v;
  }
  for (float& v : kf.global_descriptor) v = static_cast<float>(v / std::sqrt(norm));
  return kf;
}

DecodedKeyframe RoundTrip(const AirKeyframe& kf, const PacketFormat& f) {
  const aglcm::air_keyframe_t packet = EncodeKeyframe(kf, f);
  // Through LCM's own bytes, as the ground would receive them.
  std::vector<uint8_t> buffer(packet.getEncodedSize());
  EXPECT_EQ(packet.encode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  aglcm::air_keyframe_t received;
  EXPECT_EQ(received.decode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  return DecodeKeyframe(received);
}

TEST(KeyframeCodecTest, Float32IsLossless) {
  const AirKeyframe kf = MakeKeyframe(300, 64, 1);
  PacketFormat f;
  f.descriptors = ArrayEncoding::kFloat32;
  f.global = ArrayEncoding::kFloat32;
  f.scores = true;
  const DecodedKeyframe d = RoundTrip(kf, f);
  ASSERT_TRUE(d.ok) << d.error;
  EXPECT_EQ(d.keyframe.agent, kf.agent);
  EXPECT_EQ(d.keyframe.seq, kf.seq);
  EXPECT_EQ(d.keyframe.t_ns, kf.t_ns);
  EXPECT_EQ(d.keyframe.camera_id, kf.camera_id);
  EXPECT_EQ(d.keyframe.features.descriptor_type, "xfeat");
  EXPECT_TRUE(d.keyframe.T_wa_c.matrix().isApprox(kf.T_wa_c.matrix(), 1e-12));
  EXPECT_EQ(cv::norm(d.keyframe.features.descriptors, kf.features.descriptors, cv::NORM_INF), 0.0);
  for (size_t i = 0; i < 512; ++i) {
    EXPECT_FLOAT_EQ(d.keyframe.global_descriptor[i], kf.global_descriptor[i]);
  }
  // Keypoints: 640 px needs 10 integer bits, leaving 5 fractional (1/32 px).
  for (size_t i = 0; i < kf.features.size(); ++i) {
    EXPECT_LE((d.keyframe.features.keypoints[i] - kf.features.keypoints[i]).cwiseAbs().maxCoeff(),
              0.5f / 32 + 1e-6f);
    EXPECT_NEAR(d.keyframe.features.scores[i], kf.features.scores[i], 0.5 / 255 + 1e-6);
  }
}

TEST(KeyframeCodecTest, QuantisedEncodingsStayWithinTheirError) {
  const AirKeyframe kf = MakeKeyframe(500, 64, 2);
  struct Case {
    ArrayEncoding e;
    double max_abs;  // per value, for unit 64-D vectors
  };
  for (const Case& c : {Case{ArrayEncoding::kFloat16, 1e-3}, Case{ArrayEncoding::kInt8, 0.01},
                        Case{ArrayEncoding::kBits4, 0.06}}) {
    PacketFormat f;
    f.descriptors = c.e;
    f.global = c.e;
    const DecodedKeyframe d = RoundTrip(kf, f);
    ASSERT_TRUE(d.ok) << d.error;
    EXPECT_LE(cv::norm(d.keyframe.features.descriptors, kf.features.descriptors, cv::NORM_INF),
              c.max_abs)
        << ToString(c.e);
    // Quantisation keeps the matching structure: each decoded descriptor is
    // still nearest to its original among all.
    int correct = 0;
    for (int i = 0; i < 500; ++i) {
      double best = -2;
      int arg = -1;
      for (int j = 0; j < 500; ++j) {
        const double s = d.keyframe.features.descriptors.row(i).dot(kf.features.descriptors.row(j));
        if (s > best) best = s, arg = j;
      }
      correct += arg == i;
    }
    EXPECT_EQ(correct, 500) << ToString(c.e);
  }
}

TEST(KeyframeCodecTest, KeepsTheBestKeypointsAndSizeIsExact) {
  const AirKeyframe kf = MakeKeyframe(1200, 64, 3);
  for (ArrayEncoding e : {ArrayEncoding::kFloat32, ArrayEncoding::kFloat16, ArrayEncoding::kInt8,
                          ArrayEncoding::kBits4}) {
    PacketFormat f;
    f.descriptors = e;
    f.max_keypoints = 700;
    const aglcm::air_keyframe_t p = EncodeKeyframe(kf, f);
    EXPECT_EQ(p.num_keypoints, 700);
    EXPECT_EQ(EncodedKeyframeSize("uav_1", "cam0", "xfeat", 700, 64, 512, f), p.getEncodedSize());
    const DecodedKeyframe d = DecodeKeyframe(p);
    ASSERT_TRUE(d.ok);
    // The first 700 (best-scored) keypoints are the ones sent.
    EXPECT_NEAR(d.keyframe.features.keypoints[699].x(), kf.features.keypoints[699].x(), 0.02);
  }
}

TEST(KeyframeCodecTest, MalformedPacketsAreRejectedWithAReason) {
  const AirKeyframe kf = MakeKeyframe(50, 64, 4);
  const aglcm::air_keyframe_t good = EncodeKeyframe(kf, PacketFormat{});
  ASSERT_TRUE(DecodeKeyframe(good).ok);
  struct Case {
    const char* expect;
    std::function<void(aglcm::air_keyframe_t&)> corrupt;
  };
  const std::vector<Case> cases = {
      {"agent name", [](auto& p) { p.agent = "UAV 1"; }},
      {"position", [](auto& p) { p.position[1] = NAN; }},
      {"unit quaternion", [](auto& p) { p.orientation[0] = 3; }},
      {"num_keypoints", [](auto& p) { p.num_keypoints = 49; }},
      {"frac_bits", [](auto& p) { p.keypoint_frac_bits = 20; }},
      {"num_scores", [](auto& p) { p.num_scores = 3; }},
      {"unknown encoding", [](auto& p) { p.descriptors.encoding = 9; }},
      {"expected",
       [](auto& p) {
         p.descriptors.data.pop_back();
         p.descriptors.num_bytes--;
       }},
      {"vectors for",
       [](auto& p) {
         p.descriptors.count = 10;
         p.descriptors.num_scales = 10;
         p.descriptors.scales.resize(10);
         p.descriptors.data.resize(640);
         p.descriptors.num_bytes = 640;
       }},
      {"non-finite scale", [](auto& p) { p.descriptors.scales[0] = INFINITY; }},
      {"one vector",
       [](auto& p) {
         p.global_descriptor.count = 2;
         p.global_descriptor.dim = 256;
       }},
      {"descriptor_type", [](auto& p) { p.descriptor_type = ""; }},
  };
  for (const Case& c : cases) {
    aglcm::air_keyframe_t p = good;
    c.corrupt(p);
    const DecodedKeyframe d = DecodeKeyframe(p);
    EXPECT_FALSE(d.ok) << c.expect;
    EXPECT_NE(d.error.find(c.expect), std::string::npos) << "got: " << d.error;
  }
}

}  // namespace
}  // namespace ag
