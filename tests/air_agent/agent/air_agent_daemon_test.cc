// The air_agent binary, replaying the `small` scenario inside a private network
// namespace, publishes keyframe packets that a subscriber (lcm_capture)
// records; decoded, they equal what the extractor computes offline: exactly
// for float32, within the quantisation error otherwise.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "common/dataset/dataset.h"
#include "common/features/feature_extractor.h"
#include "common/wire/keyframe_codec.h"
#include "lcmtypes/checked_decode.h"
#include "tests/support/netns.h"
#include "tests/support/test_support.h"
#include "tools/sim/scenario.h"
#include "tools/sim/simulator.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

// The `small` scenario preset (seed 2), as tools/simulate writes it.
std::string WriteDataset(const std::string& dir) {
  Simulation(LoadScenario(test::SourceDir() + "/config/scenarios/small.yaml"), 2).Write(dir);
  return dir;
}

class AirAgentDaemonTest : public ::testing::TestWithParam<std::string> {};

TEST_P(AirAgentDaemonTest, PublishedPacketsDecodeToTheOfflineFeatures) {
  if (!test::CanCreateNetworkNamespace()) {
    GTEST_SKIP() << "cannot create a private network namespace (unshare -rn); LCM over UDP is "
                    "only tested inside one, so this test is skipped";
  }
  const std::string encoding = GetParam();
  test::TempDir tmp;
  const std::string dataset = WriteDataset(tmp / "dataset");
  fs::create_directories(tmp / "capture");
  std::ofstream(tmp / "air.yaml") << "features: {backend: sift, top_k: 300}\n"
                                  << "frontend:\n  governor: {encodings: [" << encoding << "]}\n";
  const std::string script =
      std::string(AG_LCM_CAPTURE) +
      " --pattern AG_AIR_KEYFRAME_uav1 --count 2 --timeout 60 --out " + (tmp / "capture") +
      " --lcm-url \"" + test::kTestLcmUrl + "\" & " + "i=0; while [ ! -f " +
      (tmp / "capture/READY") + " ] && [ $i -lt 200 ]; do sleep 0.05; i=$((i+1)); done; " +
      AG_AIR_AGENT + " --dataset " + dataset + " --agent uav1 --speed 0 --config " +
      (tmp / "air.yaml") + " --lcm-url \"" + test::kTestLcmUrl + "\" && wait $!";
  const int status = test::RunInPrivateNetwork(script, tmp / "log.txt");
  std::ifstream log_file(tmp / "log.txt");
  const std::string log((std::istreambuf_iterator<char>(log_file)),
                        std::istreambuf_iterator<char>());
  ASSERT_EQ(status, 0) << log;

  const Dataset ds = ReadDataset(dataset);
  const AgentData& uav = ds.air.at("uav1");
  FeatureOptions fo;
  fo.backend = "sift";
  fo.top_k = 300;
  const auto extractor = CreateFeatureExtractor(fo);
  for (int k = 0; k < 2; ++k) {  // 2 s at 1 keyframe per second
    const std::string path = tmp / ("capture/AG_AIR_KEYFRAME_uav1." + std::to_string(k) + ".bin");
    std::ifstream in(path, std::ios::binary);
    ASSERT_TRUE(in) << path << "\n" << log;
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
    aglcm::air_keyframe_t packet;
    ASSERT_GT(DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &packet), 0);
    const DecodedKeyframe d = DecodeKeyframe(packet);
    ASSERT_TRUE(d.ok) << d.error;
    EXPECT_EQ(d.keyframe.seq, k);
    // Keyframes at 1 Hz of 10 Hz frames: frames 0 and 10.
    const SensorFrame& frame = uav.images[10 * k];
    EXPECT_EQ(d.keyframe.t_ns, frame.t_ns);
    const Pose expected_pose =
        InterpolateInBuffer(uav.odometry, frame.t_ns).T * uav.calibration.camera.T_body_camera;
    EXPECT_TRUE(d.keyframe.T_wa_c.matrix().isApprox(expected_pose.matrix(), 1e-12));
    const LocalFeatures offline = extractor->Extract(LoadImage(frame, cv::IMREAD_UNCHANGED));
    ASSERT_EQ(d.keyframe.features.size(), offline.size());
    const double max_err =
        cv::norm(d.keyframe.features.descriptors, offline.descriptors, cv::NORM_INF);
    if (encoding == "float32") {
      EXPECT_EQ(max_err, 0.0) << "float32 must be lossless";
    } else {
      EXPECT_LT(max_err, encoding == "int8" ? 0.02 : 0.1) << encoding;
    }
    const float step = 1.0f / static_cast<float>(1 << packet.keypoint_frac_bits);
    for (size_t i = 0; i < offline.size(); ++i) {
      EXPECT_LE((d.keyframe.features.keypoints[i] - offline.keypoints[i]).cwiseAbs().maxCoeff(),
                0.5f * step + 1e-4f);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Encodings, AirAgentDaemonTest,
                         ::testing::Values("float32", "int8", "bits4"));

}  // namespace
}  // namespace ag
