#include "common/geometry/pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace ag {
namespace {

Eigen::Matrix3d RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

Eigen::Matrix3d RollPitch(double roll, double pitch) {
  return (Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

TEST(PoseTest, YawOfRecoversYawPitchRollComposition) {
  for (double yaw : {-3.0, -1.2, 0.0, 0.4, 2.9}) {
    const Eigen::Matrix3d R = RotZ(yaw) * RollPitch(0.3, -0.2);
    EXPECT_NEAR(YawOf(R), yaw, 1e-12);
  }
}

TEST(PoseTest, ProjectedYawIsExactForRotationsAboutZ) {
  for (double yaw = -M_PI + 1e-3; yaw < M_PI; yaw += 0.37) {
    EXPECT_NEAR(WrapAngle(ProjectedYaw(RotZ(yaw)) - yaw), 0.0, 1e-14);
    const Pose T = MakePose4Dof(1.0, -2.0, 3.0, yaw);
    const Pose P = ProjectTo4Dof(T);
    EXPECT_TRUE(P.matrix().isApprox(T.matrix(), 1e-14));
  }
}

TEST(PoseTest, ProjectedYawMaximisesTraceAlignment) {
  // The projection must be the closest yaw-only rotation: no other yaw gives
  // a larger trace(RotZ(yaw)^T R).
  std::mt19937 rng(7);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Matrix3d R = RandomRotation(rng);
    const double best = ProjectedYaw(R);
    const double best_trace = (RotZ(best).transpose() * R).trace();
    for (double yaw = -M_PI; yaw < M_PI; yaw += 0.01) {
      EXPECT_LE((RotZ(yaw).transpose() * R).trace(), best_trace + 1e-12);
    }
  }
}

TEST(PoseTest, ProjectTo4DofKeepsTranslationAndGivesZAxisRotation) {
  std::mt19937 rng(3);
  Pose T = Pose::Identity();
  T.linear() = RandomRotation(rng);
  T.translation() = Eigen::Vector3d(4, 5, 6);
  const Pose P = ProjectTo4Dof(T);
  EXPECT_TRUE(P.translation().isApprox(T.translation()));
  EXPECT_TRUE((P.linear() * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitZ(), 1e-14));
  EXPECT_TRUE(IsRotation(P.linear()));
}

TEST(PoseTest, WrapAngleRange) {
  EXPECT_NEAR(WrapAngle(3 * M_PI), M_PI, 1e-12);
  EXPECT_NEAR(WrapAngle(-3 * M_PI), M_PI, 1e-12);
  EXPECT_NEAR(WrapAngle(2 * M_PI + 0.5), 0.5, 1e-12);
  EXPECT_NEAR(WrapAngle(-0.5), -0.5, 1e-15);
}

TEST(PoseTest, IsRotationRejectsScaledAndReflected) {
  EXPECT_TRUE(IsRotation(RotZ(0.3)));
  EXPECT_FALSE(IsRotation(1.01 * RotZ(0.3)));
  EXPECT_FALSE(IsRotation(Eigen::Vector3d(1, 1, -1).asDiagonal()));
  Eigen::Matrix3d nan = RotZ(0.1);
  nan(0, 0) = NAN;
  EXPECT_FALSE(IsRotation(nan));
}

TEST(PoseTest, InterpolationEndpointsAndMidpoint) {
  const Pose a = MakePose4Dof(0, 0, 0, 0.2);
  const Pose b = MakePose4Dof(2, 4, -6, 0.8);
  EXPECT_TRUE(InterpolatePose(a, b, 0.0).matrix().isApprox(a.matrix(), 1e-14));
  EXPECT_TRUE(InterpolatePose(a, b, 1.0).matrix().isApprox(b.matrix(), 1e-14));
  const Pose mid = InterpolatePose(a, b, 0.5);
  EXPECT_TRUE(mid.translation().isApprox(Eigen::Vector3d(1, 2, -3)));
  EXPECT_NEAR(YawOf(mid.linear()), 0.5, 1e-12);
  // Slerp is constant-velocity: the angle from a grows linearly with s.
  std::mt19937 rng(11);
  Pose c = Pose::Identity();
  c.linear() = RandomRotation(rng);
  const Eigen::AngleAxisd full(a.linear().transpose() * c.linear());
  const Pose q = InterpolatePose(a, c, 0.25);
  const Eigen::AngleAxisd part(a.linear().transpose() * q.linear());
  EXPECT_NEAR(part.angle(), 0.25 * full.angle(), 1e-9);
}

TEST(PoseTest, BufferInterpolationRefusesToExtrapolate) {
  std::vector<StampedPose> buffer;
  EXPECT_EQ(InterpolateInBuffer(buffer, 5).status, InterpolationStatus::kEmpty);
  buffer.push_back({100, MakePose4Dof(0, 0, 0, 0)});
  buffer.push_back({200, MakePose4Dof(1, 0, 0, 0.1)});
  buffer.push_back({400, MakePose4Dof(3, 0, 0, 0.3)});
  EXPECT_EQ(InterpolateInBuffer(buffer, 99).status, InterpolationStatus::kBeforeStart);
  EXPECT_EQ(InterpolateInBuffer(buffer, 401).status, InterpolationStatus::kAfterEnd);
  const auto exact = InterpolateInBuffer(buffer, 200);
  ASSERT_TRUE(exact.ok());
  EXPECT_TRUE(exact.T.matrix().isApprox(buffer[1].T.matrix()));
  const auto mid = InterpolateInBuffer(buffer, 300);
  ASSERT_TRUE(mid.ok());
  EXPECT_NEAR(mid.T.translation().x(), 2.0, 1e-12);
  EXPECT_NEAR(YawOf(mid.T.linear()), 0.2, 1e-12);
  EXPECT_TRUE(InterpolateInBuffer(buffer, 100).ok());
  EXPECT_TRUE(InterpolateInBuffer(buffer, 400).ok());
}

}  // namespace
}  // namespace ag
