// air_agent end to end on live LCM input, and its shutdown on signals.
//
// Live: inside a private network namespace, play_dataset publishes the
// `small` scenario's UAV images and VIO, air_agent (live mode: no --dataset,
// the camera from calibration_file) turns them into keyframe packets, and
// lcm_capture records them. The packets must decode, count up, carry the
// dataset's frame times and the VIO pose interpolated at the frame times
// composed with T_body_camera; every VIO message must have arrived; SIGTERM
// then ends air_agent with status 0 and its final stats line.
//
// Dataset mode: SIGTERM or SIGINT after the first keyframe ends air_agent
// with status 0, promptly, with a final stats line. It publishes on memq://
// (in-process only), so no network is involved.

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <regex>

#include "common/dataset/dataset.h"
#include "common/wire/keyframe_codec.h"
#include "lcmtypes/checked_decode.h"
#include "tests/support/child_process.h"
#include "tests/support/netns.h"
#include "tests/support/playback_fixture.h"
#include "tests/support/test_support.h"
#include "tools/sim/scenario.h"
#include "tools/sim/simulator.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

/// The value of `key=<integer>` printed by the test script, or -1.
int64_t ScriptValue(const std::string& log, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(log, m, std::regex(key + "=(-?[0-9]+)"))) return -1;
  return std::stoll(m[1]);
}

/// The last air_agent stats line of a log ("" if none).
std::string LastStatsLine(const std::string& log, const std::string& agent, size_t from = 0) {
  const std::string tag = "] " + agent + ": frames ";
  const size_t at = log.rfind(tag);
  if (at == std::string::npos || at < from) return "";
  return log.substr(at, log.find('\n', at) - at);
}

TEST(AirAgentLive, KeyframesFromPlayedScenarioThenSigtermExitsCleanly) {
  if (!test::CanCreateNetworkNamespace()) {
    GTEST_SKIP() << "cannot create a private network namespace (unshare -rn); LCM over UDP is "
                    "only tested inside one, so this test is skipped";
  }
  test::TempDir tmp;
  const std::string dataset = tmp / "dataset";
  Simulation(LoadScenario(test::SourceDir() + "/config/scenarios/small.yaml"), 2).Write(dataset);
  const Dataset ds = ReadDataset(dataset);
  const AgentData& uav = ds.air.at("uav1");
  fs::create_directories(tmp / "capture");
  std::ofstream(tmp / "air.yaml") << "calibration_file: " << uav.dir << "/calibration.yaml\n"
                                  << "features: {backend: sift, top_k: 300}\n"
                                  << "logging: {color: false}\n";
  const std::string url = std::string("\"") + test::kTestLcmUrl + "\"";
  // Every wait is bounded: READY and "listening" polls (10 s each), the
  // capture's own timeout, the player's data (2 s), and a watchdog that
  // kills air_agent 10 s after SIGTERM.
  const std::string script =
      std::string(AG_LCM_CAPTURE) +
      " --pattern AG_AIR_KEYFRAME_uav1 --count 2 --timeout 60 --out " + (tmp / "capture") +
      " --lcm-url " + url + " & c=$!; " + "i=0; while [ ! -f " + (tmp / "capture/READY") +
      " ] && [ $i -lt 200 ]; do sleep 0.05; i=$((i+1)); done; " + AG_AIR_AGENT +
      " --agent uav1 --config " + (tmp / "air.yaml") + " --lcm-url " + url + " > " +
      (tmp / "agent.log") + " 2>&1 & a=$!; " + "i=0; while ! grep -q \"listening on\" " +
      (tmp / "agent.log") + " && [ $i -lt 200 ]; do sleep 0.05; i=$((i+1)); done; " +
      AG_PLAY_DATASET + " --dataset " + dataset + " --no-ground --speed 1 --lcm-url " + url +
      " > " + (tmp / "player.out") + " 2> " + (tmp / "player.log") + "; echo player_status=$?; " +
      "wait $c; echo capture_status=$?; " +
      "t0=$(date +%s%N); kill -TERM $a; (sleep 10; kill -KILL $a 2>/dev/null) & w=$!; " +
      "wait $a; echo agent_status=$?; t1=$(date +%s%N); kill $w 2>/dev/null; " +
      "echo agent_stop_ms=$(( (t1 - t0) / 1000000 ))";
  const auto started = std::chrono::steady_clock::now();
  const int status = test::RunInPrivateNetwork(script, tmp / "log.txt");
  const double run_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const std::string log = test::ReadFileText(tmp / "log.txt");
  const std::string agent_log = test::ReadFileText(tmp / "agent.log");
  const std::string player_out = test::ReadFileText(tmp / "player.out");
  const std::string all = log + "\n--- air_agent:\n" + agent_log + "\n--- play_dataset:\n" +
                          player_out + test::ReadFileText(tmp / "player.log");
  ASSERT_EQ(status, 0) << all;
  EXPECT_EQ(ScriptValue(log, "player_status"), 0) << all;
  EXPECT_EQ(ScriptValue(log, "capture_status"), 0) << all;
  EXPECT_EQ(ScriptValue(log, "agent_status"), 0) << "SIGTERM must end air_agent normally\n" << all;
  const int64_t stop_ms = ScriptValue(log, "agent_stop_ms");
  EXPECT_GE(stop_ms, 0) << all;
  EXPECT_LT(stop_ms, 3000) << "air_agent took too long to stop\n" << all;
  RecordProperty("script_seconds", std::to_string(run_s));

  EXPECT_NE(player_out.find("AG_AIR_ODOMETRY_uav1"), std::string::npos) << all;
  EXPECT_EQ(player_out.find("AG_UGV_"), std::string::npos) << "--no-ground\n" << all;

  for (int k = 0; k < 2; ++k) {  // keyframes at 1 Hz of 10 Hz frames: frames 0 and 10
    const std::string path = tmp / ("capture/AG_AIR_KEYFRAME_uav1." + std::to_string(k) + ".bin");
    std::ifstream in(path, std::ios::binary);
    ASSERT_TRUE(in) << path << "\n" << all;
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
    aglcm::air_keyframe_t packet;
    ASSERT_GT(DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &packet), 0);
    const DecodedKeyframe d = DecodeKeyframe(packet);
    ASSERT_TRUE(d.ok) << d.error;
    EXPECT_EQ(d.keyframe.agent, "uav1");
    EXPECT_EQ(d.keyframe.camera_id, "cam0") << "the camera the player names the images after";
    EXPECT_EQ(d.keyframe.seq, k);
    const SensorFrame& frame = uav.images[10 * k];
    EXPECT_EQ(d.keyframe.t_ns, frame.t_ns) << "keyframe " << k;
    const int64_t t_body =
        frame.t_ns + static_cast<int64_t>(std::llround(uav.calibration.camera.time_offset_s * 1e9));
    const InterpolationResult vio = InterpolateInBuffer(uav.odometry, t_body);
    ASSERT_TRUE(vio.ok());
    const Pose expected = vio.T * uav.calibration.camera.T_body_camera;
    EXPECT_TRUE(d.keyframe.T_wa_c.matrix().isApprox(expected.matrix(), 1e-9))
        << "keyframe " << k << "\n"
        << d.keyframe.T_wa_c.matrix() << "\nexpected\n"
        << expected.matrix();
    EXPECT_GT(d.keyframe.features.size(), 50u);
  }

  // The final stats line: every frame and every VIO message arrived.
  const std::string stats = LastStatsLine(agent_log, "uav1");
  EXPECT_NE(stats.find("frames " + std::to_string(uav.images.size()) + " keyframes 2"),
            std::string::npos)
      << stats << "\n"
      << all;
  EXPECT_NE(stats.find("vio poses " + std::to_string(uav.odometry.size())), std::string::npos)
      << stats;
  EXPECT_EQ(stats.find("without pose"), std::string::npos) << stats;
  EXPECT_NE(agent_log.find("air_agent stopped (signal)"), std::string::npos) << agent_log;
}

TEST(AirAgentLive, CalibrationFlagSetsTheLiveCamera) {
  test::TempDir tmp;
  test::ChildProcess agent(
      {AG_AIR_AGENT, "--calibration", tmp / "calibration.yaml", "--print-config"}, tmp / "out.txt");
  const auto status = agent.WaitFor(30);
  const std::string out = test::ReadFileText(tmp / "out.txt");
  ASSERT_TRUE(status.has_value()) << out;
  EXPECT_EQ(status->code, 0) << out;
  EXPECT_NE(out.find("calibration_file: " + (tmp / "calibration.yaml")), std::string::npos) << out;
}

TEST(AirAgentLive, MaxPartBytesFlagSplitsKeyframes) {
  test::TempDir tmp;
  test::ChildProcess agent({AG_AIR_AGENT, "--max-part-bytes", "1500", "--print-config"},
                           tmp / "out.txt");
  const auto status = agent.WaitFor(30);
  const std::string out = test::ReadFileText(tmp / "out.txt");
  ASSERT_TRUE(status.has_value()) << out;
  EXPECT_EQ(status->code, 0) << out;
  EXPECT_NE(out.find("max_part_bytes: 1500"), std::string::npos) << out;
}

class AirAgentSignalTest : public ::testing::TestWithParam<int> {};

TEST_P(AirAgentSignalTest, DatasetModeStopsCleanlyAfterAKeyframe) {
  test::TempDir tmp;
  test::PlaybackFixtureOptions fo;
  fo.duration_s = 3;  // at --speed 1, far longer than the wait for the first keyframe
  fo.air_width = 320;
  fo.air_height = 240;
  const std::string dataset = test::WritePlaybackFixture(tmp / "dataset", fo);
  std::ofstream(tmp / "air.yaml") << "features: {backend: sift, top_k: 200}\n"
                                  << "stats_period_s: 0.1\n"
                                  << "logging: {color: false}\n";
  test::ChildProcess agent({AG_AIR_AGENT, "--dataset", dataset, "--agent", "uav1", "--speed", "1",
                            "--config", tmp / "air.yaml", "--lcm-url", "memq://"},
                           tmp / "agent.log");
  // The periodic stats line shows the first keyframe published.
  const bool published = test::WaitForText(tmp / "agent.log", "keyframes 1 ", 30, &agent);
  std::string log = test::ReadFileText(tmp / "agent.log");
  ASSERT_TRUE(published) << log;
  ASSERT_TRUE(agent.Running()) << "ended before the signal\n" << log;
  const size_t log_size_at_signal = log.size();
  const auto sent = std::chrono::steady_clock::now();
  agent.Signal(GetParam());
  const auto status = agent.WaitFor(5);
  const double stop_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  log = test::ReadFileText(tmp / "agent.log");
  ASSERT_TRUE(status.has_value()) << "still running 5 s after the signal\n" << log;
  EXPECT_TRUE(status->exited) << "killed by signal " << status->signal << "\n" << log;
  EXPECT_EQ(status->code, 0) << log;
  EXPECT_LT(stop_s, 3.0) << log;
  const std::string final_stats = LastStatsLine(log, "uav1", log_size_at_signal);
  EXPECT_FALSE(final_stats.empty()) << "no stats line after the signal\n" << log;
  EXPECT_EQ(final_stats.find("keyframes 0 "), std::string::npos) << final_stats;
  EXPECT_NE(log.find("air_agent stopped (signal)", log_size_at_signal), std::string::npos) << log;
  // Stopped early: fewer frames than the 30 of the fixture.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(final_stats, m, std::regex("frames ([0-9]+) ")));
  EXPECT_LT(std::stoi(m[1]), 30) << final_stats;
}

INSTANTIATE_TEST_SUITE_P(Signals, AirAgentSignalTest, ::testing::Values(SIGTERM, SIGINT),
                         [](const ::testing::TestParamInfo<int>& info) {
                           return info.param == SIGTERM ? std::string("SIGTERM")
                                                        : std::string("SIGINT");
                         });

}  // namespace
}  // namespace ag
