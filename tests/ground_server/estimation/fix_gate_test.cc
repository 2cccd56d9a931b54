#include "ground_server/estimation/fix_gate.h"

#include <gtest/gtest.h>

namespace ag {
namespace {

constexpr int64_t kS = 1000000000LL;

// A first fix with the default gate: T offered at t - 2 s, t - 1 s and t,
// the third publishing.
void Acquire(FixGate* gate, const Pose& T, int64_t t_ns) {
  gate->Offer(t_ns - 2 * kS, T);
  gate->Offer(t_ns - kS, T);
  ASSERT_TRUE(gate->Offer(t_ns, T).publish);
}

TEST(FixGateTest, FirstFixNeedsConfirmation) {
  FixGate gate({});
  const Pose T = MakePose4Dof(1, 2, 3, 0.5);
  auto d = gate.Offer(0, T);
  EXPECT_FALSE(d.publish);
  EXPECT_EQ(d.status, FixStatus::kInitializing);
  EXPECT_NE(d.reason.find("1/3"), std::string::npos) << d.reason;
  d = gate.Offer(1 * kS, MakePose4Dof(1.05, 2, 3, 0.51));
  EXPECT_FALSE(d.publish) << "two estimates in a row share most of their data";
  EXPECT_NE(d.reason.find("2/3"), std::string::npos) << d.reason;
  d = gate.Offer(2 * kS, MakePose4Dof(1.03, 2, 3, 0.5));
  EXPECT_TRUE(d.publish);
  EXPECT_EQ(d.status, FixStatus::kTracking);
  // Close estimates publish at once.
  EXPECT_TRUE(gate.Offer(3 * kS, MakePose4Dof(1.02, 2, 3, 0.5)).publish);
}

TEST(FixGateTest, SingleOutlierIsNeverPublished) {
  FixGate gate({});
  const Pose good = MakePose4Dof(1, 2, 3, 0.5);
  Acquire(&gate, good, kS);
  // An aliased estimate 5 m away, then good ones again.
  EXPECT_FALSE(gate.Offer(2 * kS, MakePose4Dof(6, 2, 3, 0.5)).publish);
  EXPECT_TRUE(gate.fix()->translation().isApprox(good.translation()));
  EXPECT_TRUE(gate.Offer(3 * kS, good).publish);
  // Alternating aliases never confirm each other.
  FixGate fresh({});
  for (int i = 0; i < 10; ++i) {
    EXPECT_FALSE(fresh.Offer(i * kS, MakePose4Dof(i * 3.0, 0, 0, 0)).publish);
  }
  EXPECT_FALSE(fresh.fix().has_value());
}

TEST(FixGateTest, ConfirmedJumpReplacesTheFix) {
  FixGate gate({});
  Acquire(&gate, MakePose4Dof(0, 0, 0, 0), kS);
  EXPECT_FALSE(gate.Offer(2 * kS, MakePose4Dof(2, 0, 0, 0)).publish);
  const auto second = gate.Offer(3 * kS, MakePose4Dof(2, 0, 0, 0.01));
  EXPECT_FALSE(second.publish) << "a jump needs jump_confirmations (3)";
  EXPECT_NE(second.reason.find("2/3"), std::string::npos) << second.reason;
  EXPECT_TRUE(gate.Offer(4 * kS, MakePose4Dof(2.1, 0, 0, 0)).publish);
  EXPECT_NEAR(gate.fix()->translation().x(), 2.1, 1e-12);
}

TEST(FixGateTest, TwoWrongEstimatesInARowDoNotReplaceAFix) {
  // As seen on covisible seed 4 (t = 30-34 s): a 2.5 m error twice in a
  // row, then estimates that disagree with it, then good ones again.
  FixGate gate({});
  const Pose good = MakePose4Dof(0, 0, 0, 0);
  Acquire(&gate, good, kS);
  EXPECT_FALSE(gate.Offer(2 * kS, MakePose4Dof(2.5, 0, 0, 0.07)).publish);
  EXPECT_FALSE(gate.Offer(3 * kS, MakePose4Dof(2.7, 0, 0, 0.08)).publish);
  EXPECT_FALSE(gate.Offer(4 * kS, MakePose4Dof(1.0, 0, 0, 0.03)).publish);
  EXPECT_TRUE(gate.fix()->isApprox(good));
  EXPECT_TRUE(gate.Offer(5 * kS, MakePose4Dof(0.1, 0, 0, 0)).publish);
}

TEST(FixGateTest, LostAfterTimeoutAndReacquiredWithConfirmation) {
  FixGate::Options o;
  o.lost_after_s = 5;
  FixGate gate(o);
  Acquire(&gate, Pose::Identity(), kS);
  EXPECT_EQ(gate.Failed(3 * kS).status, FixStatus::kTracking);
  EXPECT_EQ(gate.Failed(7 * kS).status, FixStatus::kLost);
  EXPECT_FALSE(gate.Offer(8 * kS, Pose::Identity()).publish) << "re-acquisition is confirmed";
  EXPECT_FALSE(gate.Offer(9 * kS, Pose::Identity()).publish);
  EXPECT_TRUE(gate.Offer(10 * kS, Pose::Identity()).publish);
  EXPECT_EQ(gate.status(), FixStatus::kTracking);
}

TEST(FixGateTest, SaysWhichFixIsNewAndComparesWithTheRefinedFix) {
  FixGate gate({});
  gate.Offer(0, MakePose4Dof(0, 0, 0, 0));
  gate.Offer(kS, MakePose4Dof(0, 0, 0, 0));
  const FixGate::Decision first = gate.Offer(2 * kS, MakePose4Dof(0, 0, 0, 0));
  ASSERT_TRUE(first.publish);
  EXPECT_TRUE(first.new_fix);
  const FixGate::Decision next = gate.Offer(3 * kS, MakePose4Dof(0.1, 0, 0, 0));
  ASSERT_TRUE(next.publish);
  EXPECT_FALSE(next.new_fix) << "a continuation of the current fix";
  // The fused fix moves to 0.25 m; 0.5 m agrees with it, not with 0.1 m.
  gate.Refine(MakePose4Dof(0.25, 0, 0, 0));
  EXPECT_NEAR(gate.fix()->translation().x(), 0.25, 1e-12);
  EXPECT_TRUE(gate.Offer(4 * kS, MakePose4Dof(0.5, 0, 0, 0)).publish);
  // Refining without a fix does nothing.
  FixGate empty({});
  empty.Refine(MakePose4Dof(1, 0, 0, 0));
  EXPECT_FALSE(empty.fix().has_value());
}

// An estimate from the UAV keyframes `seqs` of 512 keypoints each, with
// `inliers` inliers.
FixEvidence From(std::vector<int64_t> seqs, int inliers = 60) {
  return {std::move(seqs), inliers, 512.0};
}

TEST(FixGateTest, WeakEstimatesFromTheSameUavKeyframesDoNotConfirmEachOther) {
  // An aliased place: every estimate repeats a 60-inlier match against UAV
  // keyframes 3 and 4 (sometimes one of them), and agrees with the last.
  FixGate gate({});
  const Pose aliased = MakePose4Dof(39, 0, 0, 0.1);
  const std::vector<std::vector<int64_t>> repeats = {{3, 4}, {3, 4}, {4}, {3}, {3, 4}, {3, 4}};
  for (size_t i = 0; i < repeats.size(); ++i) {
    const auto d = gate.Offer(static_cast<int64_t>(i) * kS, aliased, From(repeats[i]));
    EXPECT_FALSE(d.publish) << "estimate " << i;
    EXPECT_NE(d.reason.find("1/3"), std::string::npos) << d.reason;
    if (i > 0) {
      EXPECT_NE(d.reason.find("already counted"), std::string::npos) << d.reason;
    }
  }
  EXPECT_FALSE(gate.fix().has_value());
  // Estimates that each bring a UAV keyframe of their own confirm, also when
  // they reuse earlier ones.
  EXPECT_FALSE(gate.Offer(6 * kS, aliased, From({3, 4, 5})).publish);
  EXPECT_TRUE(gate.Offer(7 * kS, aliased, From({4, 5, 6})).publish);

  // So do strong repeats (repeat_min_inlier_fraction 0.15: 76.8 inliers of
  // 512 keypoints), and estimates without evidence.
  FixGate strong({});
  strong.Offer(0, aliased, From({3, 4}, 300));
  EXPECT_FALSE(strong.Offer(kS, aliased, From({3, 4}, 76)).publish);
  EXPECT_FALSE(strong.Offer(2 * kS, aliased, From({3, 4}, 77)).publish);
  EXPECT_TRUE(strong.Offer(3 * kS, aliased).publish);

  // With repeat_min_inlier_fraction 0 every agreeing estimate confirms.
  FixGate::Options options;
  options.repeat_min_inlier_fraction = 0;
  FixGate plain(options);
  plain.Offer(0, aliased, From({3, 4}));
  plain.Offer(kS, aliased, From({3, 4}));
  EXPECT_TRUE(plain.Offer(2 * kS, aliased, From({3, 4})).publish);
  options.repeat_min_inlier_fraction = -1;
  EXPECT_THROW(FixGate{options}, std::exception);

  // A jump needs new UAV keyframes too; agreeing with the current fix does not.
  const Pose right = MakePose4Dof(0, 0, 0, 0);
  FixGate tracking({});
  tracking.Offer(0, right, From({1}));
  tracking.Offer(kS, right, From({2}));
  ASSERT_TRUE(tracking.Offer(2 * kS, right, From({3})).publish);
  EXPECT_TRUE(tracking.Offer(3 * kS, right, From({3})).publish);
  for (int i = 4; i < 8; ++i) EXPECT_FALSE(tracking.Offer(i * kS, aliased, From({7, 8})).publish);
  EXPECT_TRUE(tracking.fix()->translation().isApprox(right.translation()));
  // A disagreeing estimate starts a new chain, which forgets the old one's
  // keyframes.
  EXPECT_FALSE(tracking.Offer(8 * kS, MakePose4Dof(5, 0, 0, 0), From({7, 8})).publish);
  EXPECT_FALSE(tracking.Offer(9 * kS, aliased, From({7, 8})).publish);
  EXPECT_FALSE(tracking.Offer(10 * kS, aliased, From({7, 8, 9})).publish);
  EXPECT_TRUE(tracking.Offer(11 * kS, aliased, From({10})).publish);
}

}  // namespace
}  // namespace ag
