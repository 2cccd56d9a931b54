#include "ground_server/estimation/absolute_pose.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/support/synthetic_views.h"

namespace ag {
namespace {

using test::LookAt;

constexpr double kFocal = 500.0;
constexpr double kCx = 320.0;
constexpr double kCy = 240.0;

struct Scene {
  Pose T_wa_wg;
  std::vector<Pose> T_wa_ca;
  std::vector<RayPointCorrespondence> corr;
  std::vector<bool> is_outlier;
};

// Ground points (ground plane + a few walls) seen by `frames` UAV cameras.
Scene MakeScene(uint32_t seed, int frames, int points_per_frame, double noise_px,
                double outlier_ratio) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> n(0, 1);
  Scene s;
  s.T_wa_wg = MakePose4Dof(10 * u(rng), 10 * u(rng), 2 * u(rng), M_PI * u(rng));
  for (int f = 0; f < frames; ++f) {
    // UAV above the ground-world origin area, expressed in the air world.
    const Eigen::Vector3d target_wg(3 * u(rng), 3 * u(rng), 0);
    const Eigen::Vector3d pos_wg = target_wg + Eigen::Vector3d(6 * u(rng), 6 * u(rng), 8 + u(rng));
    const Pose T_wa_ca = LookAt(s.T_wa_wg * pos_wg, s.T_wa_wg * target_wg);
    s.T_wa_ca.push_back(T_wa_ca);
    int made = 0;
    while (made < points_per_frame) {
      const double px = 640 * (u(rng) + 1) / 2;
      const double py = 480 * (u(rng) + 1) / 2;
      // Intersect the pixel ray with the ground plane z = 0 or a wall x = 4.
      const Eigen::Vector3d ray_ca((px - kCx) / kFocal, (py - kCy) / kFocal, 1);
      const Pose T_wg_ca = s.T_wa_wg.inverse() * T_wa_ca;
      const Eigen::Vector3d d = T_wg_ca.linear() * ray_ca;
      const Eigen::Vector3d o = T_wg_ca.translation();
      double lambda = -o.z() / d.z();
      if (made % 4 == 3 && std::abs(d.x()) > 1e-3) {
        const double l_wall = (4.0 - o.x()) / d.x();
        if (l_wall > 0 && l_wall < lambda && (o + l_wall * d).z() < 3) lambda = l_wall;
      }
      if (!(lambda > 0)) continue;
      RayPointCorrespondence k;
      k.p_wg = o + lambda * d;
      k.air_frame = f;
      const bool outlier = u(rng) * 0.5 + 0.5 < outlier_ratio;
      if (outlier) k.p_wg += Eigen::Vector3d(3 * u(rng), 3 * u(rng), 0.5 * u(rng));
      k.uv = Eigen::Vector2d(px + noise_px * n(rng), py + noise_px * n(rng));
      k.xy_normalized = Eigen::Vector2d((k.uv.x() - kCx) / kFocal, (k.uv.y() - kCy) / kFocal);
      k.c_wa = T_wa_ca.translation();
      k.b_wa = T_wa_ca.linear() *
               Eigen::Vector3d(k.xy_normalized.x(), k.xy_normalized.y(), 1).normalized();
      s.corr.push_back(k);
      s.is_outlier.push_back(outlier);
      ++made;
    }
  }
  return s;
}

double TranslationError(const Pose& a, const Pose& b) {
  return (a.translation() - b.translation()).norm();
}
double YawErrorDeg(const Pose& a, const Pose& b) {
  return std::abs(WrapAngle(ProjectedYaw(a.linear()) - ProjectedYaw(b.linear()))) * 180 / M_PI;
}

TEST(FourDofMinimalTest, ExactDataGivesTheTruthAmongSolutions) {
  for (uint32_t seed = 0; seed < 50; ++seed) {
    const Scene s = MakeScene(seed, 1, 2, 0.0, 0.0);
    const auto solutions = SolveFourDofMinimal(s.corr[0], s.corr[1]);
    ASSERT_FALSE(solutions.empty()) << seed;
    double best = 1e9;
    for (const Pose& T : solutions) {
      best = std::min(best, TranslationError(T, s.T_wa_wg) + YawErrorDeg(T, s.T_wa_wg));
      EXPECT_LT(AngularError(T, s.corr[0]), 1e-9);
      EXPECT_LT(AngularError(T, s.corr[1]), 1e-9);
    }
    EXPECT_LT(best, 1e-6) << seed;
  }
}

TEST(AngularErrorTest, BehindTheCameraIsInfinite) {
  RayPointCorrespondence k;
  k.c_wa = Eigen::Vector3d::Zero();
  k.b_wa = Eigen::Vector3d::UnitZ();
  k.p_wg = Eigen::Vector3d(0, 0, -5);
  EXPECT_TRUE(std::isinf(AngularError(Pose::Identity(), k)));
  k.p_wg = Eigen::Vector3d(0.1, 0, 5);
  EXPECT_NEAR(AngularError(Pose::Identity(), k), std::atan2(0.1, 5), 1e-12);
}

class RansacTest : public ::testing::TestWithParam<std::string> {};

TEST_P(RansacTest, RecoversTransformWithNoiseAndOutliers) {
  RansacOptions o;
  o.solver = GetParam();
  double worst_t = 0, worst_yaw = 0;
  for (uint32_t seed = 100; seed < 110; ++seed) {
    const Scene s = MakeScene(seed, 3, 150, 0.5, 0.4);
    const auto r = EstimateAbsolutePose(s.corr, s.T_wa_ca, kFocal, o);
    ASSERT_TRUE(r.success) << r.reason;
    worst_t = std::max(worst_t, TranslationError(r.T_wa_wg, s.T_wa_wg));
    worst_yaw = std::max(worst_yaw, YawErrorDeg(r.T_wa_wg, s.T_wa_wg));
    int true_inliers_found = 0, outliers_accepted = 0;
    for (int i : r.inliers) (s.is_outlier[i] ? outliers_accepted : true_inliers_found)++;
    EXPECT_GT(true_inliers_found, 0.9 * 0.6 * s.corr.size());
    // Outliers displaced by metres rarely fall within 3 px by chance.
    EXPECT_LT(outliers_accepted, 0.03 * s.corr.size());
  }
  // 0.5 px noise at 8-12 m with fx = 500: centimetre-level translation.
  EXPECT_LT(worst_t, 0.05) << o.solver;
  EXPECT_LT(worst_yaw, 0.3) << o.solver;
  std::printf("[ %s ] worst of 10 seeds: %.4f m, %.4f deg\n", o.solver.c_str(), worst_t, worst_yaw);
}

INSTANTIATE_TEST_SUITE_P(Solvers, RansacTest, ::testing::Values("four_dof", "epnp"));

TEST(RansacTest, FailsWithReasonOnTooFewOrGarbage) {
  RansacOptions o;
  Scene s = MakeScene(7, 1, 8, 0.5, 0.0);
  auto r = EstimateAbsolutePose(s.corr, s.T_wa_ca, kFocal, o);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.reason.find("only 8 correspondences"), std::string::npos) << r.reason;
  s = MakeScene(8, 2, 100, 0.5, 1.0);  // all outliers
  r = EstimateAbsolutePose(s.corr, s.T_wa_ca, kFocal, o);
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.reason.find("inliers"), std::string::npos) << r.reason;
}

TEST(RansacTest, DeterministicForASeed) {
  const Scene s = MakeScene(9, 2, 100, 0.5, 0.3);
  RansacOptions o;
  const auto a = EstimateAbsolutePose(s.corr, s.T_wa_ca, kFocal, o);
  const auto b = EstimateAbsolutePose(s.corr, s.T_wa_ca, kFocal, o);
  ASSERT_TRUE(a.success);
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_TRUE(a.T_wa_wg.matrix() == b.T_wa_wg.matrix());
}

}  // namespace
}  // namespace ag
