// The daemons end to end, as separate processes over LCM/UDP, always inside
// network namespaces the test creates (nothing leaves the machine), on the
// simulated `small` scenario (10 s, cached in the build folder):
//
//  ThreeProcesses: tools/play_dataset, air_agent and ground_server in one
//    private namespace. Every scan and image must arrive (the daemons' 8 MB
//    receive buffer), no message may be refused, relative poses must come
//    out on AG_RELATIVE_POSE_uav1, decode, count up, and reach TRACKING with
//    T_wa_wg within 0.5 m / 1.5 deg (median 0.35 m / 0.6 deg) of
//    groundtruth.yaml and within 3 sigma of its covariance; both daemons end
//    with status 0 on SIGTERM. relative_pose_monitor, watching beside them,
//    must see every relative pose, report the same errors against
//    groundtruth.yaml and drift-free errors within the same bounds, and
//    summarise them with their medians.
//  TwoAirAgentsAreEstimatedSideBySide: as ThreeProcesses, plus a second
//    air_agent (uav2) replaying uav1's camera from the dataset: both agents
//    get their own relative poses, within the same bounds, and neither's
//    estimation starves the other's.
//  TwoHostsThrottledLink: the UAV (player --no-ground, air_agent with a
//    0.5 Mbit/s budget) and the UGV (player --no-air, ground_server) in two
//    namespaces joined by a veth pair; the air-to-ground direction is shaped
//    by tc tbf to 0.5 Mbit/s and loses 10% of its IP packets (iptables
//    statistic: this kernel has no netem; $AG_TEST_LINK_LOSS sets another
//    fraction, e.g. 0 to see the shaping alone). air_agent sends 12 kB
//    keyframe packets at 2 Hz for the lossy link. The governor must keep every 1 s
//    window of what air_agent sent under the budget; packets must cross,
//    fixes must arrive, no daemon may crash.
//  RestartKeepsUavKeyframes: ground_server is killed (SIGKILL) after 6 s of
//    both vehicles' data, then restarted on the same persistence directory
//    and fed the UGV streams only (the UAV is gone): it must restore the UAV
//    keyframes and camera it had saved and match them without the UAV
//    resending anything.
//
// Measured numbers (CPU of each daemon, link bytes, latency from a UAV
// keyframe to the first relative pose using it) are printed and recorded as
// test properties.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <set>
#include <sstream>

#include "common/dataset/dataset.h"
#include "common/dataset/ground_truth.h"
#include "common/wire/channels.h"
#include "common/wire/keyframe_codec.h"
#include "common/wire/link_bytes.h"
#include "common/wire/message_codec.h"
#include "lcmtypes/checked_decode.h"
#include "tests/ground_server/server/daemon_fixture.h"
#include "tests/support/child_process.h"
#include "tests/support/netns.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

constexpr double kDurationS = 10.0;
constexpr uint64_t kSeed = 1;
const char* kUdpUrl = "udpm://239.255.76.67:7667?ttl=0";

#define AG_REQUIRE_NETNS()                                                                  \
  if (!test::CanCreateNetworkNamespace()) {                                                 \
    GTEST_SKIP() << "cannot create a private network namespace (unshare -rn); the daemons " \
                    "talk LCM over UDP only inside one, so this test is skipped";           \
  }

/// Runs `body` (bash, after the shared functions) in a private network
/// namespace; returns the script's output (stdout + stderr).
std::string RunScript(const test::TempDir& tmp, const std::string& body, int* status) {
  std::ofstream(tmp / "run.sh") << test::kScriptFunctions << "cd " << tmp.path() << "\n" << body;
  *status = test::RunInPrivateNetwork("bash " + (tmp / "run.sh"), tmp / "script.log");
  return test::ReadFileText(tmp / "script.log");
}

/// Every relative pose captured, decoded, in arrival order, with its
/// receive time.
struct ReceivedPose {
  int64_t recv_utime = 0;
  RelativePoseEstimate estimate;
};
std::vector<ReceivedPose> RelativePoses(const std::vector<test::Captured>& capture,
                                        const std::string& agent) {
  std::vector<ReceivedPose> out;
  for (const test::Captured& c : capture) {
    if (c.channel != RelativePoseChannel(agent)) continue;
    aglcm::relative_pose_t msg;
    ReceivedPose r;
    std::string error;
    r.recv_utime = c.recv_utime;
    EXPECT_TRUE(test::DecodeCaptured(c, &msg)) << c.path;
    EXPECT_TRUE(DecodeRelativePose(msg, &r.estimate, &error)) << c.path << ": " << error;
    out.push_back(r);
  }
  return out;
}

/// UAV keyframe packets captured: (receive time, air t_ns, link bytes).
struct ReceivedKeyframe {
  int64_t recv_utime = 0;
  int64_t t_ns = 0;
  int64_t seq = 0;
  int64_t ip_bytes = 0;
  int part = 0;  ///< of a split keyframe
};
std::vector<ReceivedKeyframe> Keyframes(const std::vector<test::Captured>& capture,
                                        const std::string& agent) {
  std::vector<ReceivedKeyframe> out;
  for (const test::Captured& c : capture) {
    if (c.channel != AirKeyframeChannel(agent)) continue;
    aglcm::air_keyframe_t msg;
    if (!test::DecodeCaptured(c, &msg)) {
      ADD_FAILURE() << "undecodable keyframe " << c.path;
      continue;
    }
    out.push_back({c.recv_utime, msg.t_ns, msg.seq, LcmLinkBytes(c.channel, c.bytes).ip, msg.part});
  }
  return out;
}

/// Configuration files of both daemons for a test run.
void WriteConfigs(const test::TempDir& tmp, const std::string& extra_ground = "",
                  const std::string& extra_air = "") {
  std::ofstream(tmp / "ground.yaml") << test::FeaturesYaml() << "stats_period_s: 1\n"
                                     << "save_period_s: 1\n"
                                     << "persistence_dir: " << (tmp / "persist") << "\n"
                                     << "logging: {color: false}\n"
                                     << extra_ground;
  std::ofstream(tmp / "air.yaml") << test::FeaturesYaml() << "stats_period_s: 1\n"
                                  << "logging: {color: false}\n"
                                  << extra_air;
}

std::string Paths(const std::string& dataset) {
  return std::string("GS=") + AG_GROUND_SERVER + "\nAIR=" + AG_AIR_AGENT +
         "\nPLAY=" + AG_PLAY_DATASET + "\nCAP=" + AG_LCM_CAPTURE + "\nMON=" + AG_MONITOR +
         "\nD=" + dataset + "\n";
}

/// The tracking fixes among `poses` and how far the best-placed last one is
/// from the truth; prints a summary.
struct FixSummary {
  int tracking = 0;
  std::optional<PoseError> last_error;
  std::vector<double> translation_m;  ///< of every TRACKING estimate
  std::vector<double> yaw_deg;
  std::vector<double> sigma_m;  ///< sqrt of the trace of the position covariance

  double Median(std::vector<double> v) const {
    std::sort(v.begin(), v.end());
    return v.empty() ? NAN : v[v.size() / 2];
  }
  double MaxOf(const std::vector<double>& v) const {
    return v.empty() ? NAN : *std::max_element(v.begin(), v.end());
  }
  /// Every fix within the worst case of the estimator's end-to-end test
  /// (tests/tools/evaluation/evaluate_sim_test.cc: 0.5 m, and 1.5 deg
  /// here) and within 3 sigma of its own covariance. The median is looser
  /// than the offline evaluator's (0.17 m on this dataset): live, timing
  /// decides which UGV windows are paired with which UAV keyframes
  /// (0.16-0.28 m median in local runs).
  void ExpectWithinBounds() const {
    EXPECT_LT(Median(translation_m), 0.35);
    EXPECT_LT(MaxOf(translation_m), 0.5);
    EXPECT_LT(Median(yaw_deg), 0.6);
    EXPECT_LT(MaxOf(yaw_deg), 1.5);
    for (size_t i = 0; i < translation_m.size(); ++i) {
      EXPECT_LT(translation_m[i], 3 * sigma_m[i]) << "fix " << i << " is overconfident";
    }
  }
};
FixSummary Fixes(const std::vector<ReceivedPose>& poses, const Pose& truth) {
  FixSummary s;
  for (const ReceivedPose& p : poses) {
    if (p.estimate.status != aglcm::relative_pose_t::TRACKING) continue;
    ++s.tracking;
    s.last_error = FourDofError(p.estimate.T_wa_wg, truth);
    s.translation_m.push_back(s.last_error->translation_m);
    s.yaw_deg.push_back(s.last_error->yaw_deg);
    s.sigma_m.push_back(std::sqrt(p.estimate.covariance.topLeftCorner<3, 3>().trace()));
    std::printf("  tracking seq %lld: error %.3f m %.2f deg (sigma %.3f m)\n",
                static_cast<long long>(p.estimate.seq), s.last_error->translation_m,
                s.last_error->yaw_deg, s.sigma_m.back());
  }
  return s;
}

/// Latency from a keyframe's arrival to the first relative pose whose
/// newest UAV keyframe is it (both as lcm_capture received them), in s.
std::vector<double> KeyframeToPoseLatencies(const std::vector<ReceivedKeyframe>& keyframes,
                                            const std::vector<ReceivedPose>& poses) {
  std::vector<double> out;
  for (const ReceivedKeyframe& k : keyframes) {
    for (const ReceivedPose& p : poses) {
      if (p.estimate.air_t_ns == k.t_ns && p.recv_utime >= k.recv_utime) {
        out.push_back(static_cast<double>(p.recv_utime - k.recv_utime) * 1e-6);
        break;
      }
    }
  }
  return out;
}

/// Script lines that start, in the test's private namespace, a capture of
/// the relative poses and keyframes of `agents` (a pattern) into cap/,
/// ground_server (pid G) and a live air_agent uav1 (pid A1, log `air_log`),
/// and wait until all listen; capture pid C, URL set.
std::string StartLive(const std::string& agents, const std::string& air_log,
                      const std::string& ground_log = "ground.log") {
  return std::string("URL='") + kUdpUrl + "'\nAGENTS='" + agents + "'\nAIRLOG=" + air_log +
         "\nGLOG=" + ground_log + "\n" + R"SH(
$CAP --pattern "AG_(RELATIVE_POSE|AIR_KEYFRAME)_$AGENTS" --count 100000 --timeout 120 --out cap --lcm-url "$URL&recv_buf_size=8388608" > cap.log 2>&1 &
C=$!
wait_for cap/READY ok 10 || echo capture_not_ready
$GS --config ground.yaml --calibration $D/ground/calibration.yaml --lcm-url "$URL" > $GLOG 2>&1 &
G=$!
$AIR --agent uav1 --config air.yaml --calibration $D/air/uav1/calibration.yaml --lcm-url "$URL" > $AIRLOG 2>&1 &
A1=$!
wait_for $GLOG 'listening on' 60 || echo ground_not_listening
wait_for $AIRLOG 'listening on' 60 || echo air_not_listening
)SH";
}

TEST(GroundServerDaemon, ThreeProcessesTrackTheSmallScenario) {
  AG_REQUIRE_NETNS();
  const std::string dataset = test::CachedSmallDataset(kDurationS, kSeed);
  const Dataset ds = ReadDataset(dataset);
  test::TempDir tmp;
  WriteConfigs(tmp);
  fs::create_directories(tmp / "cap");
  // Half speed: live, which UGV windows the ground server pairs with which
  // UAV keyframes depends on how well it keeps up. At real time, on a day
  // this 2-core VM ran ~1.7x slower than usual, the fixes' yaw errors were
  // 0.51-1.36 deg (median 0.73); at half speed, on the same day, 0.17-0.29
  // deg. The bounds below are for a machine that keeps up.
  // relative_pose_monitor watches too, as a field user (and tools/demo.sh) would.
  const std::string script = Paths(dataset) + StartLive("uav1", "air.log") + R"SH(
$MON --dataset $D --lcm-url "$URL" --quiet --require-fix --jsonl monitor.jsonl > monitor.out 2> monitor.log &
M=$!
t0=$(now)
$PLAY --dataset $D --speed 0.5 --lcm-url "$URL" > player.out 2> player.log
echo player_status=$?
sleep 3
echo wall_s=$(echo "$(now) $t0" | awk '{printf "%.2f", $1 - $2}')
echo ground_cpu_s=$(cpu_s $G)
echo air_cpu_s=$(cpu_s $A1)
stop $G ground
stop $A1 air
stop $M monitor
kill $C 2>/dev/null; wait $C
exit 0
)SH";
  int status = 0;
  const auto started = std::chrono::steady_clock::now();
  const std::string log = RunScript(tmp, script, &status);
  const double run_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const std::string ground_log = test::ReadFileText(tmp / "ground.log");
  const std::string air_log = test::ReadFileText(tmp / "air.log");
  const std::string all =
      log + "\n--- ground_server (last 6000 chars):\n" +
      ground_log.substr(ground_log.size() - std::min<size_t>(6000, ground_log.size())) +
      "\n--- air_agent (last 2000 chars):\n" +
      air_log.substr(air_log.size() - std::min<size_t>(2000, air_log.size())) + "\n--- player:\n" +
      test::ReadFileText(tmp / "player.out") + test::ReadFileText(tmp / "player.log");
  ASSERT_EQ(status, 0) << all;
  EXPECT_EQ(log.find("not_"), std::string::npos) << all;
  EXPECT_EQ(test::ScriptValue(log, "player_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "ground_status"), 0) << "ground_server must exit cleanly\n"
                                                        << all;
  EXPECT_EQ(test::ScriptValue(log, "air_status"), 0) << all;

  // Every scan and image arrived; nothing was refused.
  const std::string ugv = test::LastLineWith(ground_log, "] ugv: odometry");
  EXPECT_EQ(test::Field(ugv, "scans"), static_cast<int64_t>(ds.ground.scans.size())) << ugv;
  EXPECT_EQ(test::Field(ugv, "images"), static_cast<int64_t>(ds.ground.images.size())) << ugv;
  EXPECT_EQ(test::Field(ugv, "odometry"), static_cast<int64_t>(ds.ground.odometry.size())) << ugv;
  EXPECT_EQ(test::Field(ugv, "bad messages"), 0) << ugv;
  EXPECT_EQ(test::Field(ugv, "frame id mismatches"), 0) << ugv;
  EXPECT_EQ(test::Field(ugv, "rejected"), 0) << ugv;

  const std::vector<test::Captured> capture = test::ReadCapture(tmp / "cap");
  const std::vector<ReceivedPose> poses = RelativePoses(capture, "uav1");
  const std::vector<ReceivedKeyframe> keyframes = Keyframes(capture, "uav1");
  ASSERT_GE(poses.size(), 3u) << "relative poses on AG_RELATIVE_POSE_uav1\n" << all;
  for (size_t i = 1; i < poses.size(); ++i) {
    EXPECT_EQ(poses[i].estimate.seq, poses[i - 1].estimate.seq + 1);
  }
  EXPECT_GE(keyframes.size(), 8u) << "about one UAV keyframe per second\n" << all;

  const std::string agent_line = test::LastLineWith(ground_log, "] uav1: ");
  const Pose truth = ReadGroundTruth(dataset + "/groundtruth.yaml").T_wa_wg.at("uav1");
  const FixSummary fixes = Fixes(poses, truth);
  const std::vector<double> latencies = KeyframeToPoseLatencies(keyframes, poses);
  const double ground_cpu = test::ScriptNumber(log, "ground_cpu_s");
  const double air_cpu = test::ScriptNumber(log, "air_cpu_s");
  const double wall = test::ScriptNumber(log, "wall_s");
  std::printf(
      "three processes: %zu relative poses, %d tracking; %zu keyframes; CPU over %.1f s: "
      "ground_server %.1f s, air_agent %.1f s; script %.1f s\n  %s\n",
      poses.size(), fixes.tracking, keyframes.size(), wall, ground_cpu, air_cpu, run_s,
      agent_line.c_str());
  for (double l : latencies) std::printf("  keyframe -> relative pose: %.2f s\n", l);
  RecordProperty("relative_poses", static_cast<int>(poses.size()));
  RecordProperty("tracking", fixes.tracking);
  RecordProperty("ground_cpu_s", std::to_string(ground_cpu));
  RecordProperty("air_cpu_s", std::to_string(air_cpu));
  RecordProperty("wall_s", std::to_string(wall));

  // The fix: TRACKING, close to the truth, and the status line says so.
  ASSERT_GT(fixes.tracking, 0) << "no TRACKING relative pose in " << poses.size()
                               << " messages; last reason: '" << poses.back().estimate.status_reason
                               << "'\n"
                               << agent_line;
  fixes.ExpectWithinBounds();
  EXPECT_NE(agent_line.find("uav1: tracking"), std::string::npos) << agent_line;
  EXPECT_NE(agent_line.find("sigma"), std::string::npos) << agent_line;
  EXPECT_FALSE(latencies.empty());

  // The monitor saw every relative pose and reports the same errors against
  // groundtruth.yaml, plus drift-free ones (against the odometry worlds'
  // relation when the estimate was made) within the same bound.
  const std::string monitor_out = test::ReadFileText(tmp / "monitor.out");
  EXPECT_EQ(test::ScriptValue(log, "monitor_status"), 0)
      << "monitor --require-fix saw no fix\n"
      << monitor_out << test::ReadFileText(tmp / "monitor.log");
  EXPECT_NE(monitor_out.find("  error:"), std::string::npos) << monitor_out;
  EXPECT_NE(monitor_out.find("  drift-free:"), std::string::npos) << monitor_out;
  std::map<int64_t, const RelativePoseEstimate*> by_seq;
  for (const ReceivedPose& p : poses) by_seq[p.estimate.seq] = &p.estimate;
  std::ifstream jsonl(tmp / "monitor.jsonl");
  int lines = 0;
  std::vector<double> tracking_m, drift_free_m;
  for (std::string line; std::getline(jsonl, line); ++lines) {
    const nlohmann::json j = nlohmann::json::parse(line);
    const auto it = by_seq.find(j.at("seq").get<int64_t>());
    ASSERT_NE(it, by_seq.end()) << "the monitor reports a pose the capture lacks: " << line;
    if (it->second->status != aglcm::relative_pose_t::TRACKING) continue;
    const PoseError e = FourDofError(it->second->T_wa_wg, truth);
    EXPECT_NEAR(j.at("error_m").get<double>(), e.translation_m, 1e-4) << line;
    EXPECT_NEAR(j.at("error_deg").get<double>(), e.yaw_deg, 1e-3) << line;
    tracking_m.push_back(j.at("error_m").get<double>());
    if (!j.contains("drift_free_error_m")) continue;
    drift_free_m.push_back(j.at("drift_free_error_m").get<double>());
    EXPECT_LT(j.at("drift_free_error_m").get<double>(), 0.5) << line;
    EXPECT_LT(j.at("drift_free_error_deg").get<double>(), 1.5) << line;
  }
  std::printf("monitor: %d relative poses, %zu with a drift-free error\n", lines,
              drift_free_m.size());
  EXPECT_EQ(lines, static_cast<int>(poses.size()));
  EXPECT_FALSE(drift_free_m.empty()) << "no drift-free error in " << lines << " lines";
  // The summary's medians are those of the TRACKING lines.
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  };
  std::smatch m;
  const std::string median_line = test::LastLineWith(monitor_out, "  median:");
  ASSERT_TRUE(
      std::regex_search(median_line, m,
                        std::regex(R"(median: +([0-9.]+) m, [0-9.]+ deg over ([0-9]+) fixes; )"
                                   R"(drift-free ([0-9.]+) m, [0-9.]+ deg over ([0-9]+))")))
      << monitor_out;
  ASSERT_FALSE(tracking_m.empty());
  EXPECT_NEAR(std::stod(m[1]), median(tracking_m), 6e-4) << median_line;
  EXPECT_EQ(std::stoul(m[2]), tracking_m.size()) << median_line;
  EXPECT_NEAR(std::stod(m[3]), median(drift_free_m), 6e-4) << median_line;
  EXPECT_EQ(std::stoul(m[4]), drift_free_m.size()) << median_line;
}

TEST(GroundServerDaemon, TwoAirAgentsAreEstimatedSideBySide) {
  AG_REQUIRE_NETNS();
  const std::string dataset = test::CachedSmallDataset(kDurationS, kSeed);
  test::TempDir tmp;
  WriteConfigs(tmp);
  fs::create_directories(tmp / "cap");
  // uav1 is live (its camera and VIO played over LCM); uav2 is a second
  // air_agent replaying uav1's camera from the dataset under its own name,
  // so both have the same true T_wa_wg and reach ground_server on their own
  // channels at the same time.
  const std::string script = Paths(dataset) + StartLive("uav[12]", "air1.log") + R"SH(
$AIR --agent uav2 --dataset $D --dataset-agent uav1 --speed 1 --config air.yaml --lcm-url "$URL" > air2.log 2>&1 &
A2=$!
$PLAY --dataset $D --lcm-url "$URL" > player.out 2> player.log
echo player_status=$?
wait $A2
echo air2_status=$?
sleep 3
stop $G ground
stop $A1 air1
kill $C 2>/dev/null; wait $C
exit 0
)SH";
  int status = 0;
  const std::string log = RunScript(tmp, script, &status);
  const std::string ground_log = test::ReadFileText(tmp / "ground.log");
  const std::string all =
      log + "\n--- ground_server (last 6000 chars):\n" +
      ground_log.substr(ground_log.size() - std::min<size_t>(6000, ground_log.size())) +
      "\n--- air_agent uav2:\n" + test::ReadFileText(tmp / "air2.log");
  ASSERT_EQ(status, 0) << all;
  EXPECT_EQ(log.find("not_"), std::string::npos) << all;
  EXPECT_EQ(test::ScriptValue(log, "player_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "air2_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "ground_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "air1_status"), 0) << all;

  const std::string ugv = test::LastLineWith(ground_log, "] ugv: odometry");
  EXPECT_EQ(test::Field(ugv, "bad messages"), 0) << ugv;
  EXPECT_EQ(test::Field(ugv, "rejected"), 0) << ugv;
  EXPECT_EQ(test::Field(ugv, "unknown camera"), 0) << ugv;

  const std::vector<test::Captured> capture = test::ReadCapture(tmp / "cap");
  const Pose truth = ReadGroundTruth(dataset + "/groundtruth.yaml").T_wa_wg.at("uav1");
  std::map<std::string, int> tracking;
  for (const std::string agent : {"uav1", "uav2"}) {
    SCOPED_TRACE(agent);
    const std::vector<ReceivedPose> poses = RelativePoses(capture, agent);
    for (const ReceivedPose& p : poses) EXPECT_EQ(p.estimate.agent, agent);
    EXPECT_GE(Keyframes(capture, agent).size(), 8u) << all;
    const FixSummary fixes = Fixes(poses, truth);
    tracking[agent] = fixes.tracking;
    const std::string line = test::LastLineWith(ground_log, "] " + agent + ": ");
    std::printf("%s: %zu relative poses, %d tracking\n  %s\n", agent.c_str(), poses.size(),
                fixes.tracking, line.c_str());
    ASSERT_GT(fixes.tracking, 0) << all;
    fixes.ExpectWithinBounds();
    EXPECT_NE(line.find(agent + ": tracking"), std::string::npos) << line;
  }
  // Each agent has its own estimation thread: neither starves the other.
  EXPECT_GE(std::min(tracking["uav1"], tracking["uav2"]) * 2,
            std::max(tracking["uav1"], tracking["uav2"]))
      << "uav1 " << tracking["uav1"] << " vs uav2 " << tracking["uav2"] << " tracking fixes";
}

/// The largest sum of `bytes` over packets in any window (t - window, t]
/// ending at a packet's time t.
int64_t MaxWindowBytes(std::vector<std::pair<int64_t, int64_t>> packets, int64_t window) {
  std::sort(packets.begin(), packets.end());
  int64_t best = 0;
  for (size_t i = 0; i < packets.size(); ++i) {
    int64_t sum = 0;
    for (size_t j = 0; j <= i; ++j) {
      if (packets[j].first > packets[i].first - window) sum += packets[j].second;
    }
    best = std::max(best, sum);
  }
  return best;
}

TEST(GroundServerDaemon, TwoHostsThrottledLossyLink) {
  AG_REQUIRE_NETNS();
  const std::string dataset = test::CachedSmallDataset(kDurationS, kSeed);
  test::TempDir tmp;
  constexpr double kBudgetMbps = 0.5;
  // Keyframes split into parts of one IP packet each (frontend.max_part_bytes).
  WriteConfigs(tmp, "",
               "frontend: {keyframes: {period_s: 0.5}, governor: {budget_mbps: 0.5}, "
               "max_part_bytes: 1500}\n");
  fs::create_directories(tmp / "cap_air");
  fs::create_directories(tmp / "cap_ground");
  // The UAV namespace is the test's private one; the UGV's is a child made
  // with unshare -n, joined to it by a veth pair. Only air_agent sends with
  // ttl=1, so only its packets cross; everything else stays in its own
  // namespace (ttl=0: looped back, never transmitted).
  const std::string script = Paths(dataset) + R"SH(
URL='udpm://239.255.76.67:7667?ttl=0'
TX='udpm://239.255.76.67:7667?ttl=1'
CAPURL="$URL&recv_buf_size=8388608"
unshare -n sleep 300 &
H=$!
i=0
while [ "$(readlink /proc/$H/ns/net)" = "$(readlink /proc/self/ns/net)" ] && [ $i -lt 200 ]; do sleep 0.02; i=$((i+1)); done
ip link add va type veth peer name vg netns $H || { echo setup_failed=veth; kill $H; exit 77; }
ip addr add 10.77.0.1/24 dev va && ip link set va up && ip route replace 224.0.0.0/4 dev va || { echo setup_failed=air_side; kill $H; exit 77; }
GNS="nsenter -t $H -n"
$GNS sh -c 'ip link set lo up && ip addr add 10.77.0.2/24 dev vg && ip link set vg up && ip route add 224.0.0.0/4 dev vg' || { echo setup_failed=ground_side; kill $H; exit 77; }
# Air to ground: 0.5 Mbit/s with a queue of 4 s, and 10% of the IP packets
# (fragments, as netem would) from the air side lost on arrival (-s: the
# ground's own multicast, looped back on vg, is not the link's).
tc qdisc add dev va root tbf rate 0.5mbit burst 16kb limit 256kb || { echo setup_failed=tc_tbf; kill $H; exit 77; }
IPT=$(command -v iptables-legacy || command -v iptables || echo iptables_missing)
$GNS $IPT -t raw -A PREROUTING -i vg -s 10.77.0.1 -m statistic --mode random --probability ${AG_TEST_LINK_LOSS:-0.1} -j DROP || { echo setup_failed=iptables_statistic; kill $H; exit 77; }
$CAP --pattern 'AG_AIR_(KEYFRAME|CAMERA_INFO)_uav1' --count 100000 --timeout 120 --out cap_air --lcm-url "$CAPURL" > cap_air.log 2>&1 &
CA=$!
$GNS $CAP --pattern 'AG_(RELATIVE_POSE|AIR_KEYFRAME|AIR_CAMERA_INFO)_uav1' --count 100000 --timeout 120 --out cap_ground --lcm-url "$CAPURL" > cap_ground.log 2>&1 &
CG=$!
wait_for cap_air/READY ok 10 || echo capture_not_ready
wait_for cap_ground/READY ok 10 || echo capture_not_ready
$GNS $GS --config ground.yaml --calibration $D/ground/calibration.yaml --lcm-url "$URL" > ground.log 2>&1 &
G=$!
$AIR --agent uav1 --config air.yaml --calibration $D/air/uav1/calibration.yaml --lcm-url "$TX" > air.log 2>&1 &
A=$!
wait_for ground.log 'listening on' 60 || echo ground_not_listening
wait_for air.log 'listening on' 60 || echo air_not_listening
t0=$(now)
$GNS $PLAY --dataset $D --no-air --lcm-url "$URL" > gplayer.out 2> gplayer.log &
PG=$!
$PLAY --dataset $D --no-ground --lcm-url "$URL" > aplayer.out 2> aplayer.log &
PA=$!
wait $PG; echo ground_player_status=$?
wait $PA; echo air_player_status=$?
sleep 5
echo wall_s=$(echo "$(now) $t0" | awk '{printf "%.2f", $1 - $2}')
echo ground_cpu_s=$(cpu_s $G)
echo air_cpu_s=$(cpu_s $A)
tc -s qdisc show dev va > tc.txt
$GNS $IPT -t raw -L PREROUTING -v -n -x > iptables.txt
stop $G ground
stop $A air
kill $CA $CG 2>/dev/null; wait $CA; wait $CG
kill $H; wait $H
exit 0
)SH";
  int status = 0;
  const std::string log = RunScript(tmp, script, &status);
  if (status == 77) {
    GTEST_SKIP() << "cannot build the two-host network here (" << log
                 << "): needs veth pairs, tc tbf and iptables' statistic match in an "
                    "unprivileged network namespace";
  }
  const std::string ground_log = test::ReadFileText(tmp / "ground.log");
  const std::string air_log = test::ReadFileText(tmp / "air.log");
  const std::string tc = test::ReadFileText(tmp / "tc.txt");
  const std::string ipt = test::ReadFileText(tmp / "iptables.txt");
  const std::string all =
      log + "\n--- tc:\n" + tc + "--- iptables:\n" + ipt + "\n--- ground_server (end):\n" +
      ground_log.substr(ground_log.size() - std::min<size_t>(5000, ground_log.size())) +
      "\n--- air_agent (end):\n" +
      air_log.substr(air_log.size() - std::min<size_t>(3000, air_log.size()));
  ASSERT_EQ(status, 0) << all;
  EXPECT_EQ(log.find("not_"), std::string::npos) << all;
  EXPECT_EQ(test::ScriptValue(log, "ground_player_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "air_player_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "ground_status"), 0) << "ground_server crashed?\n" << all;
  EXPECT_EQ(test::ScriptValue(log, "air_status"), 0) << "air_agent crashed?\n" << all;

  // What air_agent sent (captured in its own namespace, before the link):
  // every 1 s window under the budget, in its camera clock (the governor's
  // guarantee) and, as a check of the real sending times, in wall time.
  const int64_t budget_bytes = static_cast<int64_t>(kBudgetMbps * 1e6 / 8);
  std::vector<std::pair<int64_t, int64_t>> by_camera_time, by_wall_time;
  int64_t sent_bytes = 0, sent_parts = 0, sent_infos = 0;
  std::set<int64_t> sent_seqs;
  for (const test::Captured& c : test::ReadCapture(tmp / "cap_air")) {
    const int64_t ip = LcmLinkBytes(c.channel, c.bytes).ip;
    int64_t t_ns = 0;
    if (c.channel == AirKeyframeChannel("uav1")) {
      aglcm::air_keyframe_t m;
      ASSERT_TRUE(test::DecodeCaptured(c, &m)) << c.path;
      t_ns = m.t_ns;
      ++sent_parts;
      sent_seqs.insert(m.seq);
    } else {
      aglcm::camera_info_t m;
      ASSERT_TRUE(test::DecodeCaptured(c, &m)) << c.path;
      t_ns = m.t_ns;
      ++sent_infos;
    }
    by_camera_time.emplace_back(t_ns, ip);
    by_wall_time.emplace_back(c.recv_utime * 1000, ip);
    sent_bytes += ip;
  }
  const int64_t max_camera_window = MaxWindowBytes(by_camera_time, 1000000000);
  const int64_t max_wall_window = MaxWindowBytes(by_wall_time, 1000000000);
  const int64_t sent_keyframes = static_cast<int64_t>(sent_seqs.size());
  EXPECT_GE(sent_keyframes, 5) << all;
  EXPECT_GT(sent_parts, 2 * sent_keyframes) << "keyframes were not split into parts\n" << all;
  // Without its camera_info the ground can use none of the keyframes.
  EXPECT_GT(sent_infos, 0) << "air_agent sent no camera_info under the budget\n" << all;
  EXPECT_LE(max_camera_window, budget_bytes) << "bytes in a 1 s window of camera time\n" << all;
  // In wall time (what the link sees) the governor promises nothing: a
  // keyframe processed late and the next on time leave less than 1 s apart
  // (the player falls behind on this loaded machine). Reported, not asserted.

  // What crossed the link.
  const std::vector<test::Captured> ground_capture = test::ReadCapture(tmp / "cap_ground");
  int64_t arrived_infos = 0;
  for (const test::Captured& c : ground_capture) {
    arrived_infos += c.channel == AirCameraInfoChannel("uav1");
  }
  const std::vector<ReceivedKeyframe> arrived = Keyframes(ground_capture, "uav1");
  std::set<int64_t> arrived_seqs;
  for (const ReceivedKeyframe& k : arrived) arrived_seqs.insert(k.seq);
  const int64_t arrived_keyframes = static_cast<int64_t>(arrived_seqs.size());
  const int64_t arrived_parts = static_cast<int64_t>(arrived.size());
  const std::vector<ReceivedPose> poses = RelativePoses(ground_capture, "uav1");
  const Pose truth = ReadGroundTruth(dataset + "/groundtruth.yaml").T_wa_wg.at("uav1");
  const FixSummary fixes = Fixes(poses, truth);
  // Time on the link (queue of the shaper included), per keyframe that crossed.
  const std::vector<ReceivedKeyframe> sent = Keyframes(test::ReadCapture(tmp / "cap_air"), "uav1");
  for (const ReceivedKeyframe& k : arrived) {
    for (const ReceivedKeyframe& s : sent) {
      if (s.seq == k.seq && s.part == k.part && k.part == 0) {
        std::printf("  keyframe %lld: %.2f s on the link\n", static_cast<long long>(k.seq),
                    static_cast<double>(k.recv_utime - s.recv_utime) * 1e-6);
      }
    }
  }
  const std::string ugv = test::LastLineWith(ground_log, "] ugv: odometry");
  const std::string agent_line = test::LastLineWith(ground_log, "] uav1: ");
  std::smatch tc_sent;
  std::regex_search(tc, tc_sent,
                    std::regex("Sent ([0-9]+) bytes ([0-9]+) pkt \\(dropped ([0-9]+)"));
  const std::string ipt_drop = test::LastLineWith(ipt, "DROP");
  const double wall = test::ScriptNumber(log, "wall_s");
  std::printf(
      "throttled link: air_agent sent %lld keyframes in %lld parts, %lld camera infos, %lld IP "
      "bytes (%.3f "
      "Mbit/s over %.1f s); "
      "max 1 s window %lld B camera time, %lld B wall time (budget %lld B); tc: %s; "
      "iptables: %s; "
      "arrived: %lld keyframes in %lld parts, %lld camera infos; %zu relative poses, %d "
      "tracking; CPU "
      "ground_server %.1f s air_agent %.1f s\n  %s\n  %s\n",
      static_cast<long long>(sent_keyframes), static_cast<long long>(sent_parts),
      static_cast<long long>(sent_infos), static_cast<long long>(sent_bytes),
      static_cast<double>(sent_bytes) * 8e-6 / std::max(wall, 1.0), wall,
      static_cast<long long>(max_camera_window), static_cast<long long>(max_wall_window),
      static_cast<long long>(budget_bytes), tc_sent.empty() ? "?" : tc_sent[0].str().c_str(),
      ipt_drop.c_str(), static_cast<long long>(arrived_keyframes),
      static_cast<long long>(arrived_parts), static_cast<long long>(arrived_infos), poses.size(),
      fixes.tracking, test::ScriptNumber(log, "ground_cpu_s"), test::ScriptNumber(log, "air_cpu_s"),
      ugv.c_str(), agent_line.c_str());
  RecordProperty("sent_keyframes", static_cast<int>(sent_keyframes));
  RecordProperty("sent_camera_infos", static_cast<int>(sent_infos));
  RecordProperty("arrived_keyframes", static_cast<int>(arrived_keyframes));
  RecordProperty("sent_parts", static_cast<int>(sent_parts));
  RecordProperty("arrived_parts", static_cast<int>(arrived_parts));
  RecordProperty("max_camera_window_bytes", static_cast<int>(max_camera_window));
  RecordProperty("max_wall_window_bytes", static_cast<int>(max_wall_window));
  RecordProperty("tracking", fixes.tracking);

  // Packets cross the link and the server keeps working on them, and fixes
  // arrive. A camera_info is one IP packet (90% cross); a keyframe of ~30 kB
  // sent whole would be ~21 (0.9^21: 11% cross, as LCM has no retransmission
  // or FEC), so air_agent splits it into parts of one IP packet each: ~90% of
  // the keypoints cross, and a keyframe is lost only with its part 0 (10%).
  EXPECT_GT(arrived_infos, 0) << "no camera_info crossed the link\n" << all;
  EXPECT_NE(agent_line.find("uav1: "), std::string::npos) << "the server never saw uav1\n" << all;
  EXPECT_FALSE(poses.empty()) << "ground_server published no relative pose\n" << all;
  EXPECT_GT(fixes.tracking, 0) << "no fix over the throttled, lossy link\n" << all;
  EXPECT_EQ(test::Field(ugv, "bad messages"), 0) << ugv;
}

/// The first index of `poses` where seq starts again (a restarted server).
size_t RestartIndex(const std::vector<ReceivedPose>& poses) {
  for (size_t i = 1; i < poses.size(); ++i) {
    if (poses[i].estimate.seq <= poses[i - 1].estimate.seq) return i;
  }
  return poses.size();
}

/// The lines of `text` that contain `what`.
std::string Grep(const std::string& text, const std::string& what) {
  std::string out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.find(what) != std::string::npos) out += line + "\n";
  }
  return out;
}

TEST(GroundServerDaemon, RestartKeepsUavKeyframes) {
  AG_REQUIRE_NETNS();
  const std::string dataset = test::CachedSmallDataset(kDurationS, kSeed);
  test::TempDir tmp;
  WriteConfigs(tmp);
  fs::create_directories(tmp / "cap");
  const std::string script = Paths(dataset) + StartLive("uav1", "air.log", "ground1.log") + R"SH(
$PLAY --dataset $D --duration-s 6 --lcm-url "$URL" > player1.out 2> player1.log
echo player1_status=$?
sleep 2.5
kill -KILL $G; wait $G; echo ground1_status=$?
stop $A1 air
# The UAV is gone: only the keyframes saved before the crash exist.
$GS --config ground.yaml --calibration $D/ground/calibration.yaml --lcm-url "$URL" > ground2.log 2>&1 &
G=$!
wait_for ground2.log 'listening on' 60 || echo ground_not_listening
$PLAY --dataset $D --no-air --lcm-url "$URL" > player2.out 2> player2.log
echo player2_status=$?
sleep 3
stop $G ground2
kill $C 2>/dev/null; wait $C
exit 0
)SH";
  int status = 0;
  const std::string log = RunScript(tmp, script, &status);
  const std::string log1 = test::ReadFileText(tmp / "ground1.log");
  const std::string log2 = test::ReadFileText(tmp / "ground2.log");
  const std::string all = log + "\n--- ground1:\n" + Grep(log1, "] uav1") + Grep(log1, "] ugv") +
                          "--- ground2:\n" + Grep(log2, "restore") + Grep(log2, "] uav1") +
                          Grep(log2, "] ugv") + Grep(log2, "rror");
  ASSERT_EQ(status, 0) << all;
  EXPECT_EQ(log.find("not_"), std::string::npos) << all;
  EXPECT_EQ(test::ScriptValue(log, "player1_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "player2_status"), 0) << all;
  EXPECT_EQ(test::ScriptValue(log, "ground1_status"), 128 + 9) << "killed by SIGKILL\n" << all;
  EXPECT_EQ(test::ScriptValue(log, "ground2_status"), 0) << all;

  // Before the crash: keyframes stored. After: the same number restored
  // (the last ones were snapshotted within save_period_s), with the camera.
  const int64_t stored =
      test::Field(test::LastLineWith(log1, "] ugv: odometry"), "keyframes stored");
  EXPECT_GE(stored, 4) << all;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      log2, m,
      std::regex("restored ([0-9]+) UAV keyframes of 'uav1' \\(seq up to ([0-9]+)\\) and "
                 "([0-9]+) camera")))
      << all;
  EXPECT_EQ(std::stoll(m[1]), stored) << all;
  EXPECT_EQ(std::stoll(m[3]), 1) << all;

  // The restarted server estimates with them, the UAV sending nothing.
  const std::string agent_line = test::LastLineWith(log2, "] uav1: ");
  EXPECT_NE(agent_line.find("packets 0 received"), std::string::npos) << agent_line;
  const std::vector<ReceivedPose> poses = RelativePoses(test::ReadCapture(tmp / "cap"), "uav1");
  const size_t restart = RestartIndex(poses);
  ASSERT_LT(restart + 3, poses.size()) << "too few relative poses after the restart\n" << all;
  int matched = 0;
  for (size_t i = restart; i < poses.size(); ++i) {
    const std::string& reason = poses[i].estimate.status_reason;
    if (reason.rfind("no UAV keyframe to match", 0) != 0 &&
        reason.rfind("no UGV keyframe yet", 0) != 0) {
      ++matched;
    }
  }
  EXPECT_GT(matched, 0) << "the restored keyframes were never matched\n" << all;
  const Pose truth = ReadGroundTruth(dataset + "/groundtruth.yaml").T_wa_wg.at("uav1");
  const FixSummary fixes = Fixes(
      std::vector<ReceivedPose>(poses.begin() + static_cast<std::ptrdiff_t>(restart), poses.end()),
      truth);
  std::printf(
      "restart: %lld stored before the crash, restored %s; %zu relative poses after, %d "
      "matched restored keyframes, %d tracking\n  %s\n",
      static_cast<long long>(stored), m[1].str().c_str(), poses.size() - restart, matched,
      fixes.tracking, agent_line.c_str());
  RecordProperty("tracking_after_restart", fixes.tracking);
  // A fix from the restored keyframes alone.
  ASSERT_GT(fixes.tracking, 0) << "no TRACKING relative pose after the restart; last reason: '"
                               << poses.back().estimate.status_reason << "'\n"
                               << agent_line;
  // The estimation's bound on `small` (tests/tools/evaluation): recovery is
  // what this test is about, accuracy is measured there.
  EXPECT_LT(fixes.last_error->translation_m, 0.5);
  EXPECT_LT(fixes.last_error->yaw_deg, 1.5);
}

}  // namespace
}  // namespace ag
