#include "ground_server/estimation/fix_filter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/core/error.h"

namespace ag {
namespace {

constexpr int64_t kS = 1000000000LL;

Eigen::Vector4d Xyzyaw(const Pose& T) {
  return {T.translation().x(), T.translation().y(), T.translation().z(), ProjectedYaw(T.linear())};
}

FixFilter::Options NoDrift(double weight) {
  FixFilter::Options o;
  o.drift_translation_m = 0;
  o.drift_yaw_deg = 0;
  o.weight = weight;
  return o;
}

TEST(FixFilterTest, IndependentEstimatesOfAConstantAverageDown) {
  // Without drift and with weight 1 the filter is the weighted mean: 100
  // estimates of 0.5 m / 1 deg noise end within a few sigma / 10.
  FixFilter filter(NoDrift(1.0));
  const Eigen::Vector4d truth(10, -5, 2, 0.3);
  const Eigen::Vector4d sigma(0.5, 0.5, 0.5, M_PI / 180);
  const Eigen::Matrix4d R = sigma.cwiseAbs2().asDiagonal();
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  double single_sq = 0;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector4d z =
        truth + sigma.cwiseProduct(Eigen::Vector4d(n(rng), n(rng), n(rng), n(rng)));
    single_sq += (z - truth).head<3>().squaredNorm();
    filter.Update(i * kS, MakePose4Dof(z[0], z[1], z[2], z[3]), R);
  }
  const Eigen::Vector4d e = Xyzyaw(filter.T_wa_wg()) - truth;
  EXPECT_LT(e.head<3>().norm(), 3 * 0.5 * std::sqrt(3.0) / 10) << e.transpose();
  EXPECT_LT(std::abs(e[3]), 3 * (M_PI / 180) / 10);
  EXPECT_LT(e.head<3>().squaredNorm(), single_sq / 100 / 10) << "no better than one estimate";
  // Its covariance is R / 100.
  EXPECT_NEAR(filter.covariance()(0, 0), 0.25 / 100, 1e-9);
  EXPECT_NEAR(filter.covariance()(3, 3), std::pow(M_PI / 180, 2) / 100, 1e-12);
}

TEST(FixFilterTest, EachDirectionIsWeightedByItsOwnCertainty) {
  FixFilter filter(NoDrift(1.0));
  filter.Update(0, MakePose4Dof(0, 0, 0, 0), Eigen::Vector4d(0.01, 0.01, 0.01, 1e-6).asDiagonal());
  // x poorly determined by the second estimate, y well: x stays, y moves.
  filter.Update(kS, MakePose4Dof(1, 1, 0, 0), Eigen::Vector4d(100, 1e-4, 0.01, 1e-6).asDiagonal());
  const Eigen::Vector4d x = Xyzyaw(filter.T_wa_wg());
  EXPECT_LT(std::abs(x[0]), 1e-3);
  EXPECT_GT(x[1], 0.98);
}

TEST(FixFilterTest, CorrelatedErrorsAlongARidgeAreAveragedAcrossIt) {
  // Two estimates whose yaw and x errors trade against each other along
  // different directions (a yaw error about different far pivots): each is
  // off by 1 m along its own ridge, the fused one much less.
  auto ridge = [](double lever_m) {
    Eigen::Matrix4d P = Eigen::Matrix4d::Identity() * 1e-4;
    Eigen::Vector4d d(lever_m, 0, 0, 1.0);  // 1 rad of yaw moves x by lever_m
    P += 0.01 * d * d.transpose();
    return P;
  };
  FixFilter filter(NoDrift(1.0));
  filter.Update(0, MakePose4Dof(1.0, 0, 0, 1.0 / 50), ridge(50));
  filter.Update(kS, MakePose4Dof(-1.0, 0, 0, 1.0 / 50), ridge(-50));
  const Eigen::Vector4d x = Xyzyaw(filter.T_wa_wg());
  EXPECT_LT(std::abs(x[0]), 0.05) << x.transpose();
}

TEST(FixFilterTest, DriftLetsTheFixFollowAMovingRelation) {
  FixFilter::Options o;
  o.drift_translation_m = 0.5;
  o.weight = 1.0;
  FixFilter filter(o);
  const Eigen::Matrix4d R = Eigen::Vector4d(0.01, 0.01, 0.01, 1e-4).asDiagonal();
  for (int i = 0; i < 20; ++i) filter.Update(i * kS, MakePose4Dof(0.1 * i, 0, 0, 0), R);
  // The relation moved 1.9 m; the fix lags it by less than 0.1 m.
  EXPECT_NEAR(filter.T_wa_wg().translation().x(), 1.9, 0.1);
  // Without drift it would average the whole path.
  FixFilter still(NoDrift(1.0));
  for (int i = 0; i < 20; ++i) still.Update(i * kS, MakePose4Dof(0.1 * i, 0, 0, 0), R);
  EXPECT_NEAR(still.T_wa_wg().translation().x(), 0.95, 0.01);
}

TEST(FixFilterTest, AJumpInUavTimeLetsTheFixFollow) {
  // Estimates one second apart, but the second from UAV keyframes 30 s
  // older: the relation may have drifted by 30 s of UAV odometry, so the
  // fix follows it much further than after one second.
  FixFilter::Options o;
  const Eigen::Matrix4d R = Eigen::Vector4d(0.01, 0.01, 0.01, 1e-6).asDiagonal();
  FixFilter same(o), jump(o);
  same.Update(0, MakePose4Dof(0, 0, 0, 0), R, 40 * kS);
  same.Update(kS, MakePose4Dof(1, 0, 0, 0), R, 40 * kS);
  jump.Update(0, MakePose4Dof(0, 0, 0, 0), R, 40 * kS);
  jump.Update(kS, MakePose4Dof(1, 0, 0, 0), R, 10 * kS);
  const double x_same = same.T_wa_wg().translation().x();
  const double x_jump = jump.T_wa_wg().translation().x();
  EXPECT_GT(x_jump, x_same + 0.1);
  // The first estimate's variance 0.01 plus the random walk, 0.04^2 per
  // second of (1 + 30) s, against the second's 0.01 / weight 0.25.
  EXPECT_NEAR(x_jump, 0.0596 / (0.0596 + 0.04), 1e-6);
  EXPECT_NEAR(x_same, 0.0116 / (0.0116 + 0.04), 1e-6);
}

TEST(FixFilterTest, WeightBelowOneKeepsTheCovarianceHonestForSharedData) {
  FixFilter full(NoDrift(1.0)), quarter(NoDrift(0.25));
  const Eigen::Matrix4d R = Eigen::Vector4d(0.04, 0.04, 0.04, 1e-4).asDiagonal();
  for (int i = 0; i < 8; ++i) {
    full.Update(i * kS, MakePose4Dof(0, 0, 0, 0), R);
    quarter.Update(i * kS, MakePose4Dof(0, 0, 0, 0), R);
  }
  EXPECT_NEAR(full.covariance()(0, 0), 0.04 / 8, 1e-9);
  // The first estimate counts whole (it shares nothing yet), the other 7 a
  // quarter each: information 1 + 7 / 4 = 11 / 4 times one estimate's.
  EXPECT_NEAR(quarter.covariance()(0, 0), 0.04 * 4 / 11, 1e-9);
}

TEST(FixFilterTest, YawIsFusedAcrossTheWrap) {
  FixFilter filter(NoDrift(1.0));
  const Eigen::Matrix4d R = Eigen::Vector4d(0.01, 0.01, 0.01, 1e-4).asDiagonal();
  filter.Update(0, MakePose4Dof(0, 0, 0, M_PI - 0.01), R);
  filter.Update(kS, MakePose4Dof(0, 0, 0, -M_PI + 0.01), R);
  EXPECT_NEAR(std::abs(Xyzyaw(filter.T_wa_wg())[3]), M_PI, 1e-6);
}

TEST(FixFilterTest, ResetStartsOverAndDisabledPublishesEachEstimate) {
  FixFilter filter(NoDrift(1.0));
  const Eigen::Matrix4d R = Eigen::Matrix4d::Identity() * 0.01;
  filter.Update(0, MakePose4Dof(0, 0, 0, 0), R);
  filter.Reset(kS, MakePose4Dof(5, 0, 0, 0), R);
  EXPECT_DOUBLE_EQ(filter.T_wa_wg().translation().x(), 5);
  EXPECT_DOUBLE_EQ(filter.covariance()(0, 0), 0.01);
  // An estimate not after the last starts over too.
  filter.Update(kS, MakePose4Dof(7, 0, 0, 0), R);
  EXPECT_DOUBLE_EQ(filter.T_wa_wg().translation().x(), 7);

  FixFilter::Options off;
  off.enabled = false;
  FixFilter plain(off);
  plain.Update(0, MakePose4Dof(0, 0, 0, 0), R);
  plain.Update(kS, MakePose4Dof(1, 0, 0, 0), R);
  EXPECT_DOUBLE_EQ(plain.T_wa_wg().translation().x(), 1);
}

TEST(FixFilterTest, BadOptionsAreNamed) {
  FixFilter::Options o;
  o.weight = 0;
  try {
    FixFilter f(o);
    FAIL() << "weight 0 accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("weight"), std::string::npos) << e.what();
  }
  o = {};
  o.drift_yaw_deg = -1;
  EXPECT_THROW(FixFilter{o}, std::exception);
}

}  // namespace
}  // namespace ag
