// AirFrontend with split keyframes (frontend.max_part_bytes): every packet
// fits its limit, the governor's budget holds over the parts, and the parts
// join back into the keyframe that was planned.
#include "air_agent/frontend/air_frontend.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "common/core/error.h"
#include "common/wire/channels.h"
#include "common/wire/keyframe_assembler.h"

namespace ag {
namespace {

CameraCalibration TestCalibration() {
  CameraCalibration c;
  c.camera.width = 640;
  c.camera.height = 480;
  c.camera.fx = c.camera.fy = 400;
  c.camera.cx = 320;
  c.camera.cy = 240;
  return c;
}

/// Blurred noise: SIFT finds hundreds of keypoints in it.
cv::Mat TexturedImage() {
  cv::Mat image(480, 640, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(image, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 2.0);
  return image;
}

struct Extractors {
  std::unique_ptr<FeatureExtractor> features;
  std::unique_ptr<GlobalDescriptorExtractor> global;
  Extractors() {
    FeatureOptions f;
    f.backend = "sift";
    f.top_k = 600;
    features = CreateFeatureExtractor(f);
    global = CreateGlobalDescriptorExtractor(GlobalDescriptorOptions{}, features->type());
  }
};

AirFrontend::Options SplitOptions(int64_t max_part_bytes) {
  AirFrontend::Options o;
  o.keyframes.period_s = 0.5;
  o.governor.budget_mbps = 0.2;  // 25 kB per second: fewer keypoints than extracted
  o.governor.max_keypoints = 600;
  o.governor.min_keypoints = 64;
  o.max_part_bytes = max_part_bytes;
  return o;
}

TEST(AirFrontendTest, SplitKeyframesFitTheirPartsAndTheBudget) {
  const Extractors x;
  AirFrontend frontend("uav1", SplitOptions(1500), TestCalibration(), x.features.get(),
                       x.global.get());
  const cv::Mat image = TexturedImage();
  KeyframeAssembler assembler;
  std::vector<std::pair<int64_t, int64_t>> sent;  // (t_ns, IP bytes) of every packet
  int keyframes = 0;
  for (int i = 0; i < 40; ++i) {  // 4 s at 10 Hz
    const int64_t t_ns = 1000000000LL + i * 100000000LL;
    const AirFrontend::Output out =
        frontend.ProcessFrame(t_ns, image, MakePose4Dof(0.1 * i, 0, 5, 0));
    if (!out.keyframe) continue;
    ++keyframes;
    ASSERT_GT(out.packets.size(), 1u) << "hundreds of keypoints do not fit one 1500-byte packet";
    int64_t ip = 0;
    std::string error;
    std::vector<KeyframeAssembler::Joined> joined;
    for (const aglcm::air_keyframe_t& p : out.packets) {
      const LinkBytes b = LcmLinkBytes(AirKeyframeChannel("uav1"), p.getEncodedSize());
      EXPECT_LE(b.ip, 1500);
      EXPECT_EQ(b.datagrams, 1);
      ip += b.ip;
      sent.emplace_back(t_ns, b.ip);
      DecodedKeyframe d = DecodeKeyframe(p);
      ASSERT_TRUE(d.ok) << d.error;
      for (auto& j : assembler.Add(std::move(d), 0.0, &error)) joined.push_back(std::move(j));
      EXPECT_EQ(error, "");
    }
    EXPECT_EQ(out.link.ip, ip);  // what the governor counted is what goes on the link
    ASSERT_EQ(joined.size(), 1u);
    EXPECT_EQ(static_cast<int>(joined[0].keyframe.features.size()), out.keypoints);
    EXPECT_GE(out.keypoints, 64);
    EXPECT_EQ(joined[0].keyframe.global_descriptor.size(), static_cast<size_t>(x.global->dim()));
  }
  EXPECT_GE(keyframes, 6);  // every 0.5 s, each with its share of the budget
  // Every 1 s window of camera time within the budget (25000 B).
  for (const auto& [t_end, unused] : sent) {
    int64_t bytes = 0;
    for (const auto& [t, b] : sent) bytes += (t > t_end - 1000000000LL && t <= t_end) ? b : 0;
    EXPECT_LE(bytes, 25000) << "window ending at " << t_end;
  }
}

TEST(AirFrontendTest, APartTooSmallForTheGlobalDescriptorIsNamed) {
  const Extractors x;
  try {
    AirFrontend frontend("uav1", SplitOptions(600), TestCalibration(), x.features.get(),
                         x.global.get());
    FAIL() << "600-byte parts cannot carry a float16 global descriptor";
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("max_part_bytes"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ag
