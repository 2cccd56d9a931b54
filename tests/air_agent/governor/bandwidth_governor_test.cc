#include "air_agent/governor/bandwidth_governor.h"

#include <gtest/gtest.h>

#include <vector>

#include "common/core/error.h"

namespace ag {
namespace {

constexpr int64_t kSecond = 1000000000LL;

// A packet model in the spirit of the real codec: fixed part + per keypoint
// (4 bytes of coordinates + 64 descriptor values at the encoding's width).
int64_t ModelBytes(int keypoints, ArrayEncoding e) {
  const double per_value = e == ArrayEncoding::kFloat32   ? 4.0
                           : e == ArrayEncoding::kFloat16 ? 2.0
                           : e == ArrayEncoding::kInt8    ? 1.0
                                                          : 0.5;
  const int64_t scales = e == ArrayEncoding::kInt8 ? 4 : e == ArrayEncoding::kBits4 ? 8 : 0;
  return 1200 + keypoints * (4 + static_cast<int64_t>(64 * per_value) + scales);
}

struct Sent {
  int64_t t_ns;
  int64_t bytes;
};

// Max bytes over every window [s, s + 1 s) whose start is a packet time (the
// worst windows start at a packet).
int64_t MaxWindowBytes(const std::vector<Sent>& sent) {
  int64_t worst = 0;
  for (size_t i = 0; i < sent.size(); ++i) {
    int64_t sum = 0;
    for (size_t j = i; j < sent.size() && sent[j].t_ns < sent[i].t_ns + kSecond; ++j) {
      sum += sent[j].bytes;
    }
    worst = std::max(worst, sum);
  }
  return worst;
}

// Runs keyframes at `rate_hz` for `seconds` and returns what was sent.
std::vector<Sent> RunKeyframes(BandwidthGovernor& g, double rate_hz, int seconds,
                               std::vector<BandwidthGovernor::Plan>* plans = nullptr) {
  std::vector<Sent> sent;
  const int64_t step = static_cast<int64_t>(kSecond / rate_hz);
  for (int64_t t = 0; t < seconds * kSecond; t += step) {
    const auto plan = g.PlanKeyframe(t, 1500);
    if (plans) plans->push_back(plan);
    if (!plan.send) continue;
    EXPECT_EQ(plan.bytes, ModelBytes(plan.keypoints, plan.encoding));
    EXPECT_TRUE(g.TryConsume(t, plan.bytes)) << "a plan that does not fit at t=" << t;
    sent.push_back({t, plan.bytes});
  }
  return sent;
}

TEST(BandwidthGovernorTest, UnlimitedSendsEverything) {
  BandwidthGovernor::Options o;
  BandwidthGovernor g(o, ModelBytes);
  const auto plan = g.PlanKeyframe(0, 5000);
  EXPECT_TRUE(plan.send);
  EXPECT_EQ(plan.keypoints, 1024);
  EXPECT_EQ(plan.encoding, ArrayEncoding::kInt8);
  EXPECT_TRUE(plan.gave_up.empty());
  const auto few = g.PlanKeyframe(kSecond, 300);
  EXPECT_EQ(few.keypoints, 300);
}

TEST(BandwidthGovernorTest, AmpleBudgetGivesUpNothing) {
  BandwidthGovernor::Options o;
  o.budget_mbps = 1.0;  // 125 kB/s; a full int8 packet is ~73 kB
  BandwidthGovernor g(o, ModelBytes);
  std::vector<BandwidthGovernor::Plan> plans;
  const auto sent = RunKeyframes(g, 1.0, 30, &plans);
  EXPECT_EQ(sent.size(), 30u);
  for (const auto& p : plans) {
    EXPECT_EQ(p.keypoints, 1024);
    EXPECT_TRUE(p.gave_up.empty());
  }
}

TEST(BandwidthGovernorTest, LowersKeypointsFirstThenEncodingThenRate) {
  BandwidthGovernor::Options o;
  o.encodings = {"float32", "int8"};
  o.min_keypoints = 256;
  // 1. Budget between float32@256 and float32@1024: fewer keypoints, float32.
  o.budget_mbps = ModelBytes(600, ArrayEncoding::kFloat32) * 8.0 / 1e6;
  {
    BandwidthGovernor g(o, ModelBytes);
    std::vector<BandwidthGovernor::Plan> plans;
    RunKeyframes(g, 1.0, 20, &plans);
    for (const auto& p : plans) {
      ASSERT_TRUE(p.send);
      EXPECT_EQ(p.encoding, ArrayEncoding::kFloat32);
      EXPECT_NEAR(p.keypoints, 600, 1);
      EXPECT_NE(p.gave_up.find("keypoints 1024 -> "), std::string::npos) << p.gave_up;
    }
  }
  // 2. float32@256 does not fit, int8 does: next encoding, keypoints restored.
  o.budget_mbps = ModelBytes(200, ArrayEncoding::kFloat32) * 8.0 / 1e6;
  {
    BandwidthGovernor g(o, ModelBytes);
    std::vector<BandwidthGovernor::Plan> plans;
    RunKeyframes(g, 1.0, 20, &plans);
    for (const auto& p : plans) {
      ASSERT_TRUE(p.send);
      EXPECT_EQ(p.encoding, ArrayEncoding::kInt8);
      EXPECT_GT(p.keypoints, 600);
      EXPECT_NE(p.gave_up.find("encoding float32 -> int8"), std::string::npos) << p.gave_up;
    }
  }
  // 3. Even int8@256 does not fit in one second: keyframes are skipped, and
  //    what is sent still respects the budget.
  o.budget_mbps = ModelBytes(256, ArrayEncoding::kInt8) * 8.0 / 1e6 / 2.5;
  {
    BandwidthGovernor g(o, ModelBytes);
    std::vector<BandwidthGovernor::Plan> plans;
    const auto sent = RunKeyframes(g, 1.0, 30, &plans);
    EXPECT_GT(g.keyframes_skipped(), 0);
    EXPECT_LT(sent.size(), 30u);
    int skipped_messages = 0;
    for (const auto& p : plans) {
      if (!p.send) skipped_messages += p.gave_up.find("keyframe skipped") != std::string::npos;
    }
    EXPECT_EQ(skipped_messages, g.keyframes_skipped());
  }
}

TEST(BandwidthGovernorTest, NeverExceedsBudgetInAnyWindow) {
  for (double budget : {0.1, 0.3, 0.5, 1.0, 2.0}) {
    for (double rate : {0.5, 1.0, 3.0, 10.0}) {
      BandwidthGovernor::Options o;
      o.budget_mbps = budget;
      o.encodings = {"float16", "int8", "bits4"};
      BandwidthGovernor g(o, ModelBytes);
      const auto sent = RunKeyframes(g, rate, 20);
      ASSERT_FALSE(sent.empty()) << budget << " Mbps at " << rate << " Hz";
      EXPECT_LE(MaxWindowBytes(sent), g.window_budget_bytes())
          << budget << " Mbps " << rate << " Hz";
      // And it uses the link: at least 40% of what the budget or the full
      // packets at this rate would allow (one packet per window at most uses
      // one window's budget, so 0.5 Hz can use only half).
      int64_t total = 0;
      for (const Sent& s : sent) total += s.bytes;
      const int64_t achievable = std::min<int64_t>(
          g.window_budget_bytes() * 20,
          static_cast<int64_t>(20 * rate) * ModelBytes(1024, ArrayEncoding::kFloat16));
      EXPECT_GE(total, achievable * 4 / 10) << budget << " Mbps " << rate << " Hz";
    }
  }
}

TEST(BandwidthGovernorTest, KeyframesAtTheirIntervalShareTheBudgetEvenly) {
  // 0.4 Mbit/s = 50 kB per second for keyframes due every 0.5 s: a full int8
  // keyframe (~74 kB) fits neither, so each gets fewer keypoints.
  BandwidthGovernor::Options o;
  o.budget_mbps = 0.4;
  o.min_keypoints = 128;
  std::vector<BandwidthGovernor::Plan> one_window;
  {
    BandwidthGovernor g(o, ModelBytes);
    RunKeyframes(g, 2.0, 20, &one_window);
  }
  o.keyframe_interval_s = 0.5;
  BandwidthGovernor g(o, ModelBytes);
  std::vector<BandwidthGovernor::Plan> shared;
  const auto sent = RunKeyframes(g, 2.0, 20, &shared);
  EXPECT_LE(MaxWindowBytes(sent), g.window_budget_bytes());
  // With one window of tokens, a keyframe takes what two would share, and
  // the next waits: about every other one is skipped.
  int one_window_sent = 0;
  for (const auto& p : one_window) one_window_sent += p.send;
  EXPECT_LT(one_window_sent, 30);
  // Shared: every keyframe after the first goes, each with about half a
  // second of budget (25 kB: ~300 int8 keypoints).
  for (size_t i = 1; i < shared.size(); ++i) {
    ASSERT_TRUE(shared[i].send) << "keyframe " << i << ": " << shared[i].gave_up;
    EXPECT_NEAR(static_cast<double>(shared[i].bytes), 25000.0, 2500.0) << "keyframe " << i;
  }
}

TEST(BandwidthGovernorTest, AShareBelowTheSmallestKeyframeStillSendsSome) {
  BandwidthGovernor::Options o;
  o.budget_mbps = ModelBytes(256, ArrayEncoding::kBits4) * 8.0 / 1e6;  // one per second
  o.keyframe_interval_s = 0.1;  // a tenth of that per keyframe: never enough
  BandwidthGovernor g(o, ModelBytes);
  const auto sent = RunKeyframes(g, 10.0, 10);
  EXPECT_GE(sent.size(), 8u);
  EXPECT_LE(MaxWindowBytes(sent), g.window_budget_bytes());
}

TEST(BandwidthGovernorTest, OtherTrafficCountsAndIsRefusedWhenFull) {
  BandwidthGovernor::Options o;
  o.budget_mbps = 0.08;  // 10 kB per second
  BandwidthGovernor g(o, ModelBytes);
  EXPECT_TRUE(g.TryConsume(0, 9000));
  EXPECT_FALSE(g.TryConsume(kSecond / 2, 2000));
  EXPECT_EQ(g.BytesInWindow(kSecond / 2), 9000);
  EXPECT_TRUE(g.TryConsume(kSecond + 1, 9000));
  EXPECT_EQ(g.BytesInWindow(kSecond + 1), 9000);
}

TEST(BandwidthGovernorTest, KeyframesLeaveTheReserveForCameraInfo) {
  // A budget keyframes alone would fill: at 0.5 Mbit/s, 1 Hz, every window
  // still has room for a 400-byte camera info.
  BandwidthGovernor::Options o;
  o.budget_mbps = 0.5;
  BandwidthGovernor g(o, ModelBytes);
  g.SetReserve(400);
  for (int s = 0; s < 10; ++s) {
    const int64_t t = s * kSecond;
    const auto plan = g.PlanKeyframe(t, 1500);
    ASSERT_TRUE(plan.send);
    EXPECT_LE(plan.bytes, g.window_budget_bytes() - 400);
    ASSERT_TRUE(g.TryConsume(t, plan.bytes));
    EXPECT_TRUE(g.TryConsume(t + kSecond / 2, 400)) << "no room for camera info at " << s << " s";
  }
  // Without the reserve the keyframes take it all.
  BandwidthGovernor greedy(o, ModelBytes);
  int refused = 0;
  for (int s = 0; s < 10; ++s) {
    const int64_t t = s * kSecond;
    const auto plan = greedy.PlanKeyframe(t, 1500);
    if (plan.send) greedy.TryConsume(t, plan.bytes);
    refused += greedy.TryConsume(t + kSecond / 2, 400) ? 0 : 1;
  }
  EXPECT_GT(refused, 5);
}

TEST(BandwidthGovernorTest, PacketCapHoldsWithOrWithoutABudget) {
  for (const double budget : {0.0, 2.0}) {
    BandwidthGovernor::Options o;
    o.budget_mbps = budget;
    o.max_packet_bytes = 16000;
    BandwidthGovernor g(o, ModelBytes);
    std::vector<BandwidthGovernor::Plan> plans;
    RunKeyframes(g, 1.0, 5, &plans);
    for (const auto& plan : plans) {
      ASSERT_TRUE(plan.send) << budget;
      EXPECT_LE(plan.bytes, 16000) << budget;
      EXPECT_GT(plan.bytes, 16000 - 100) << "the cap should be used, not undershot";
    }
  }
}

TEST(BandwidthGovernorTest, OptionsAreChecked) {
  BandwidthGovernor::Options o;
  o.encodings = {"int7"};
  EXPECT_THROW(o.Check(), OptionError);
  o = {};
  o.min_keypoints = 2000;
  EXPECT_THROW(o.Check(), OptionError);
  o = {};
  o.budget_mbps = -1;
  EXPECT_THROW(o.Check(), OptionError);
}

}  // namespace
}  // namespace ag
