#include "tools/sim/odometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "common/config/options.h"
#include "tests/support/test_support.h"
#include "tools/sim/random.h"
#include "tools/sim/scenario.h"

namespace ag {
namespace {

constexpr double kDeg = M_PI / 180.0;

/// A true trajectory: a circle at 1 m/s, tilting a little (roll / pitch),
/// sampled at the odometry rate.
std::vector<StampedPose> Truth(double duration_s, double rate_hz) {
  std::vector<StampedPose> out;
  const auto period = static_cast<int64_t>(std::llround(1e9 / rate_hz));
  for (int64_t k = 0; k * period <= static_cast<int64_t>(duration_s * 1e9); ++k) {
    const double t = static_cast<double>(k * period) * 1e-9;
    StampedPose s;
    s.t_ns = 1000000000 + k * period;
    s.T.linear() = (Eigen::AngleAxisd(0.05 * t, Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(0.02 * std::sin(t), Eigen::Vector3d::UnitX()) *
                    Eigen::AngleAxisd(0.03 * std::cos(0.7 * t), Eigen::Vector3d::UnitY()))
                       .toRotationMatrix();
    s.T.translation() =
        Eigen::Vector3d(20.0 * std::sin(0.05 * t), 20.0 * (1.0 - std::cos(0.05 * t)), 0.3);
    out.push_back(s);
  }
  return out;
}

struct Stats {
  double mean = 0.0, std = 0.0;
};
Stats Of(const std::vector<double>& v) {
  Stats s;
  for (double x : v) s.mean += x;
  s.mean /= static_cast<double>(v.size());
  for (double x : v) s.std += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(s.std / static_cast<double>(v.size() - 1));
  return s;
}

TEST(SimOdometry, YawDriftMatchesTheScenarioOverManySeeds) {
  // The drift the covisible preset asks for, from its YAML.
  const std::string path = test::SourceDir() + "/config/scenarios/covisible.yaml";
  const OdometryOptions o = LoadScenario(path).options.ground.odometry;
  ASSERT_GT(o.yaw_random_walk_deg_per_sqrt_s, 0.0);
  const double T = 60.0;
  const auto truth = Truth(T, o.rate_hz);
  std::vector<double> yaw_error;
  for (uint64_t seed = 0; seed < 400; ++seed) {
    SimRandom rng(seed, "odometry_test");
    const auto odom = SimulateOdometry(truth, o, rng);
    ASSERT_EQ(odom.size(), truth.size());
    EXPECT_TRUE(odom.front().T.translation().isApprox(truth.front().T.translation()));
    // Roll and pitch stay gravity-aligned: the gravity direction seen in the
    // body frame is the true one (up to the white yaw noise, which is about z).
    const Eigen::Matrix3d& R_o = odom.back().T.linear();
    const Eigen::Matrix3d& R_t = truth.back().T.linear();
    EXPECT_LT((R_o.transpose().col(2) - R_t.transpose().col(2)).norm(), 1e-9);
    yaw_error.push_back(WrapAngle(YawOf(R_o * R_t.transpose())));
  }
  const Stats s = Of(yaw_error);
  const double expected_mean = o.yaw_drift_deg_per_min / 60.0 * T * kDeg;
  const double expected_std = std::sqrt(std::pow(o.yaw_random_walk_deg_per_sqrt_s * kDeg, 2) * T +
                                        std::pow(o.yaw_noise_deg * kDeg, 2));
  // 400 samples: the mean is known to std / 20, the std to ~4 %.
  EXPECT_NEAR(s.mean, expected_mean, 4.0 * expected_std / 20.0);
  EXPECT_NEAR(s.std, expected_std, 0.15 * expected_std);
}

TEST(SimOdometry, TranslationRandomWalkAndScaleMatchTheOptions) {
  const YAML::Node yaml = YAML::Load(
      "rate_hz: 100\n"
      "xy_random_walk_m_per_sqrt_s: 0.01\n"
      "z_random_walk_m_per_sqrt_s: 0.004\n");
  const OdometryOptions o = LoadOptions<OdometryOptions>(yaml, "test");
  const double T = 50.0;
  const auto truth = Truth(T, o.rate_hz);
  std::vector<double> ex, ey, ez;
  for (uint64_t seed = 0; seed < 400; ++seed) {
    SimRandom rng(seed, "odometry_test");
    const auto odom = SimulateOdometry(truth, o, rng);
    const Eigen::Vector3d e = odom.back().T.translation() - truth.back().T.translation();
    ex.push_back(e.x());
    ey.push_back(e.y());
    ez.push_back(e.z());
  }
  const double sxy = o.xy_random_walk_m_per_sqrt_s * std::sqrt(T),
               sz = o.z_random_walk_m_per_sqrt_s * std::sqrt(T);
  for (const auto* v : {&ex, &ey}) {
    const Stats s = Of(*v);
    EXPECT_NEAR(s.mean, 0.0, 4.0 * sxy / 20.0);
    EXPECT_NEAR(s.std, sxy, 0.15 * sxy);
  }
  const Stats s = Of(ez);
  EXPECT_NEAR(s.std, sz, 0.15 * sz);

  // Scale error alone: the odometry's travelled distance is (1 + e) times the true one.
  OdometryOptions scale;
  scale.scale_error = 0.01;
  SimRandom rng(1);
  const auto odom = SimulateOdometry(truth, scale, rng);
  double true_len = 0.0, odom_len = 0.0;
  for (size_t k = 1; k < truth.size(); ++k) {
    true_len += (truth[k].T.translation() - truth[k - 1].T.translation()).norm();
    odom_len += (odom[k].T.translation() - odom[k - 1].T.translation()).norm();
  }
  EXPECT_NEAR(odom_len / true_len, 1.01, 1e-9);
}

}  // namespace
}  // namespace ag
