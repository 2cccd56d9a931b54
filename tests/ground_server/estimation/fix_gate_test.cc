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

}  // namespace
}  // namespace ag
