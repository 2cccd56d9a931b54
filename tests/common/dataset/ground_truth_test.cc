// The ground-truth comparisons the evaluator and the live monitor share:
// the 4-DoF error, and the relation of two drifting odometry worlds that
// an estimator can observe instead of groundtruth.yaml.
#include "common/dataset/ground_truth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace ag {
namespace {

constexpr int64_t kSecond = 1000000000LL;

void ExpectPoseNear(const Pose& a, const Pose& b, double tol = 1e-9) {
  EXPECT_LT((a.translation() - b.translation()).norm(), tol);
  EXPECT_LT((a.linear() - b.linear()).norm(), tol);
}

/// A body moving for 10 s (true world) whose odometry world sits at
/// `T_world_odom` in the true one: odometry = T_world_odom^-1 * truth.
AgentData DriftingAgent(const Pose& T_world_odom) {
  AgentData agent;
  for (int i = 0; i <= 10; ++i) {
    const Pose truth = MakePose4Dof(2.0 * i, 0.5 * i, 1.0, 0.1 * i);
    agent.groundtruth.push_back({i * kSecond, truth});
    agent.odometry.push_back({i * kSecond, T_world_odom.inverse() * truth});
  }
  return agent;
}

TEST(FourDofError, MeasuresTranslationAndWrappedYaw) {
  const PoseError e =
      FourDofError(MakePose4Dof(1.0, 2.0, 3.0, M_PI - 0.01), MakePose4Dof(1.0, 5.0, 7.0, -M_PI));
  EXPECT_NEAR(e.translation_m, 5.0, 1e-12);
  EXPECT_NEAR(e.yaw_deg, 0.01 * 180.0 / M_PI, 1e-9) << "yaw wraps across +-180 deg";
}

TEST(OdometryWorldInTrueWorld, IsTheDriftAndEmptyOutsideTheTrajectories) {
  const Pose drift = MakePose4Dof(0.3, -0.2, 0.05, 0.02);
  const AgentData agent = DriftingAgent(drift);
  const std::optional<Pose> at = OdometryWorldInTrueWorld(agent, 4 * kSecond + kSecond / 2);
  ASSERT_TRUE(at.has_value());
  ExpectPoseNear(*at, drift);
  EXPECT_FALSE(OdometryWorldInTrueWorld(agent, 11 * kSecond).has_value());
  AgentData no_truth = agent;
  no_truth.groundtruth.clear();
  EXPECT_FALSE(OdometryWorldInTrueWorld(no_truth, 5 * kSecond).has_value())
      << "without groundtruth.tum there is no drift to tell";
}

TEST(LidarMountOffset, IsTrueTimesNominalInverseAndIdentityWithoutTheTruth) {
  Dataset dataset;
  ExpectPoseNear(LidarMountOffset(dataset), Pose::Identity());
  const Pose nominal = MakePose4Dof(0.1, 0.0, 0.3, 0.0);
  const Pose truth = MakePose4Dof(0.1, 0.01, 0.3, 0.015);
  dataset.ground.calibration.lidar = LidarCalibration{nominal};
  dataset.groundtruth = DatasetGroundTruth{};
  ExpectPoseNear(LidarMountOffset(dataset), Pose::Identity());
  dataset.groundtruth->ground_true_lidar = LidarCalibration{truth};
  ExpectPoseNear(LidarMountOffset(dataset) * nominal, truth);
}

TEST(ObservableTruth, MapsTheUgvOdometryPoseToWhereTheUavOdometryWorldHasIt) {
  const Pose T_wa_wg = MakePose4Dof(-1.3, 6.8, -3.1, 2.07);
  const Pose air_drift = MakePose4Dof(0.2, 0.1, -0.05, 0.01);
  const Pose ground_drift = MakePose4Dof(-0.4, 0.3, 0.02, -0.015);
  Dataset dataset;
  dataset.ground = DriftingAgent(ground_drift);
  const AgentData air = DriftingAgent(air_drift);

  // Without drift on either side the observable relation is groundtruth.yaml.
  const AgentData air_exact = DriftingAgent(Pose::Identity());
  Dataset exact = dataset;
  exact.ground = DriftingAgent(Pose::Identity());
  const std::optional<Pose> same = ObservableTruth(exact, air_exact, kSecond, kSecond, T_wa_wg);
  ASSERT_TRUE(same.has_value());
  ExpectPoseNear(*same, T_wa_wg);

  // With drift: the UGV's odometry pose, mapped by the observable relation,
  // lands where the UGV truly is, expressed in the UAV's odometry world.
  const int64_t t_air = 3 * kSecond, t_ground = 7 * kSecond;
  const std::optional<Pose> observable = ObservableTruth(dataset, air, t_air, t_ground, T_wa_wg);
  ASSERT_TRUE(observable.has_value());
  const Pose ugv_true_wg = dataset.ground.groundtruth[7].T;
  const Pose ugv_odometry = dataset.ground.odometry[7].T;
  ExpectPoseNear(*observable * ugv_odometry, air_drift.inverse() * T_wa_wg * ugv_true_wg, 1e-9);
  EXPECT_GT(FourDofError(*observable, T_wa_wg).translation_m, 0.1) << "the drift shows";

  EXPECT_FALSE(ObservableTruth(dataset, air, 20 * kSecond, t_ground, T_wa_wg).has_value())
      << "a keyframe time outside the UAV's trajectories";
}

}  // namespace
}  // namespace ag
