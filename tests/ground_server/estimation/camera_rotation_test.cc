#include "ground_server/estimation/camera_rotation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "common/core/error.h"
#include "ground_server/estimation/cost_functions.h"
#include "tests/support/option_error.h"
#include "tests/support/synthetic_views.h"

namespace ag {
namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d Rotation(double deg, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(deg * kDeg, axis.normalized()).toRotationMatrix();
}

double AngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() / kDeg;
}

/// A UGV camera 0.5 m above flat ground driving an L (straight, then a
/// 90 deg turn) past two walls, its LIO camera poses off by a constant
/// mounting rotation. Observations are what the estimator collects: a
/// keypoint's ray in a host keyframe with the map plane under it, and its
/// (noisy) match in a later keyframe.
struct LScene {
  std::vector<Pose> truth;    // true camera poses
  std::vector<Pose> nominal;  // LIO x nominal extrinsic = truth * correction^-1
  std::vector<Eigen::Vector4d> planes = {{0, 0, 1, 0}, {0, 1, 0, -6}, {1, 0, 0, -14}};
  Camera camera{test::Pinhole640x480()};

  explicit LScene(const Eigen::Matrix3d& correction) {
    Pose C = Pose::Identity();
    C.linear() = correction;
    for (int i = 0; i < 12; ++i) {
      const Eigen::Vector3d pos =
          i < 6 ? Eigen::Vector3d(1.2 * i, 0, 0.5) : Eigen::Vector3d(7.2, 1.2 * (i - 6), 0.5);
      const Eigen::Vector3d ahead =
          i < 6 ? Eigen::Vector3d(1, 0.05, -0.02) : Eigen::Vector3d(0.05, 1, -0.02);
      truth.push_back(test::LookAt(pos, pos + ahead));
      nominal.push_back(truth.back() * C.inverse());
    }
  }

  /// Observations of random plane points, with pixel noise and a fraction of
  /// wrong matches.
  std::vector<std::pair<std::tuple<int64_t, int, int64_t>, PlaneTrackObservation>> Observe(
      int n, double noise_px, double outlier_fraction, uint32_t seed) const {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::normal_distribution<double> g(0, 1);
    std::vector<std::pair<std::tuple<int64_t, int, int64_t>, PlaneTrackObservation>> out;
    const double fx = camera.params().fx;
    for (int k = 0; static_cast<int>(out.size()) < n && k < 100 * n; ++k) {
      const int host = static_cast<int>(u(rng) * 11);
      const int obs = host + 1;
      // A pixel of the host, cut with the true geometry.
      const Eigen::Vector2d f_host((u(rng) - 0.5) * 1.2, (u(rng) - 0.5) * 0.9);
      const Eigen::Vector3d ray = truth[host].linear() * f_host.homogeneous();
      int best = -1;
      double depth = std::numeric_limits<double>::infinity();
      for (int p = 0; p < static_cast<int>(planes.size()); ++p) {
        const double s = -(planes[p].head<3>().dot(truth[host].translation()) + planes[p][3]) /
                         planes[p].head<3>().dot(ray);
        if (s > 0.5 && s < depth) depth = s, best = p;
      }
      if (best < 0 || depth > 25) continue;
      const Eigen::Vector3d p_c = truth[obs].inverse() * (truth[host].translation() + depth * ray);
      if (p_c.z() < 0.5) continue;
      Eigen::Vector2d f_obs = p_c.head<2>() / p_c.z();
      if (std::abs(f_obs.x()) > 0.6 || std::abs(f_obs.y()) > 0.45) continue;
      f_obs += noise_px / fx * Eigen::Vector2d(g(rng), g(rng));
      if (u(rng) < outlier_fraction) f_obs += 6.0 / fx * Eigen::Vector2d(g(rng), g(rng));
      PlaneTrackObservation o;
      o.T_wg_c_host = nominal[host];
      o.f_host = f_host;
      o.plane = planes[best];
      o.T_wg_c_obs = nominal[obs];
      o.f_obs = f_obs;
      o.focal_px = fx;
      out.push_back({{host, k, obs}, o});
    }
    return out;
  }
};

TEST(PlaneCutReprojectionTest, VanishesAtTheTrueCorrectionOnly) {
  const Eigen::Matrix3d correction = Rotation(1.0, {0.4, -1.0, 0.3});
  const LScene scene(correction);
  const auto obs = scene.Observe(50, 0.0, 0.0, 3);
  ASSERT_EQ(obs.size(), 50u);
  const Eigen::AngleAxisd aa(correction);
  const Eigen::Vector3d d_true = aa.angle() * aa.axis();
  double worst_at_truth = 0, sum_at_zero = 0;
  for (const auto& [key, o] : obs) {
    const PlaneCutReprojectionError f(o, o.focal_px);
    double r[2];
    const double no_offset = 0;
    ASSERT_TRUE(f(d_true.data(), &no_offset, r));
    worst_at_truth = std::max(worst_at_truth, std::hypot(r[0], r[1]));
    const double zero[3] = {0, 0, 0};
    if (f(zero, &no_offset, r)) sum_at_zero += std::hypot(r[0], r[1]);
  }
  EXPECT_LT(worst_at_truth, 1e-6);
  // Uncorrected, the cuts land elsewhere: pixels of error on average.
  EXPECT_GT(sum_at_zero / obs.size(), 1.0);
}

TEST(PlaneCutReprojectionTest, AnalyticJacobiansMatchAutodiff) {
  // Random corrections up to 3 deg (and exactly zero, where the rotations
  // take their first-order branch), time offsets up to 50 ms, turning up to
  // 30 deg/s and speeds up to 3 m/s, on the L scene's observations.
  const LScene scene(Rotation(1.0, {0.4, -1.0, 0.3}));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto random3 = [&](double scale) -> Eigen::Vector3d {
    return Eigen::Vector3d(u(rng), u(rng), u(rng)) * scale;
  };
  int compared = 0;
  int trial = 0;
  for (auto [key, o] : scene.Observe(200, 0.5, 0.05, 13)) {
    o.omega_host_c = random3(30 * kDeg);
    o.v_host_wg = random3(3);
    o.omega_obs_c = random3(30 * kDeg);
    o.v_obs_wg = random3(3);
    const bool at_zero = trial % 10 == 0;
    const Eigen::Vector3d d = at_zero ? Eigen::Vector3d::Zero() : random3(3 * kDeg);
    const double dt = at_zero ? 0.0 : 0.05 * u(rng);
    const double* params[2] = {d.data(), &dt};
    std::unique_ptr<ceres::CostFunction> autodiff(PlaneCutReprojectionError::Create(o, 500));
    const PlaneCutReprojectionCost analytic(o, 500);
    double r_auto[2], r_analytic[2], Jd_auto[6], Jt_auto[2], Jd_analytic[6], Jt_analytic[2];
    double* ja[2] = {Jd_auto, Jt_auto};
    double* jb[2] = {Jd_analytic, Jt_analytic};
    const bool ok = autodiff->Evaluate(params, r_auto, ja);
    ASSERT_EQ(analytic.Evaluate(params, r_analytic, jb), ok) << "trial " << trial;
    ++trial;
    if (!ok) continue;
    ++compared;
    for (int k = 0; k < 2; ++k) {
      EXPECT_NEAR(r_analytic[k], r_auto[k], 1e-9 * (1 + std::abs(r_auto[k])));
      EXPECT_NEAR(Jt_analytic[k], Jt_auto[k], 1e-8 * (1 + std::abs(Jt_auto[k])));
    }
    for (int k = 0; k < 6; ++k) {
      EXPECT_NEAR(Jd_analytic[k], Jd_auto[k], 1e-8 * (1 + std::abs(Jd_auto[k])))
          << "entry " << k << " trial " << trial;
    }
    double r_only[2];
    ASSERT_TRUE(analytic.Evaluate(params, r_only, nullptr));
    EXPECT_EQ(r_only[0], r_analytic[0]);
  }
  EXPECT_GE(compared, 180) << "most observations must cut their plane in front of the camera";

  // A cut behind the host camera rejects the step in both.
  PlaneTrackObservation behind = scene.Observe(1, 0, 0, 13).front().second;
  const Eigen::Vector3d z = behind.T_wg_c_host.linear().col(2);  // the host's optical axis
  behind.plane << z, -z.dot(behind.T_wg_c_host.translation() - 5 * z);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  const double no_offset = 0;
  const double* params[2] = {zero.data(), &no_offset};
  double r[2];
  std::unique_ptr<ceres::CostFunction> autodiff(PlaneCutReprojectionError::Create(behind, 500));
  EXPECT_FALSE(autodiff->Evaluate(params, r, nullptr));
  EXPECT_FALSE(PlaneCutReprojectionCost(behind, 500).Evaluate(params, r, nullptr));
}

TEST(CameraRotationCalibratorTest, RecoversAConstantMountingRotation) {
  // 1 deg about an oblique axis (pitch, yaw and roll all off), 0.7 px noise
  // and 5 % wrong matches of ~6 px.
  for (const Eigen::Vector3d& axis :
       {Eigen::Vector3d(1, 0.3, -0.5), Eigen::Vector3d(-0.2, 0.4, 1)}) {
    const Eigen::Matrix3d correction = Rotation(1.0, axis);
    const LScene scene(correction);
    CameraRotationCalibrator::Options o;
    o.max_observations = 3000;
    CameraRotationCalibrator calibrator(o);
    for (const auto& [key, obs] : scene.Observe(3000, 0.7, 0.05, 5)) calibrator.Add(key, obs);
    const CameraRotationCalibrator::SolveResult r = calibrator.Solve();
    ASSERT_TRUE(r.updated) << r.reason;
    EXPECT_TRUE(calibrator.has_estimate());
    const double error = AngleDeg(calibrator.rotation(), correction);
    std::printf("axis (%.1f %.1f %.1f): residual error %.3f deg of 1 deg, rms %.2f -> %.2f px\n",
                axis.x(), axis.y(), axis.z(), error, r.initial_rms_px, r.final_rms_px);
    EXPECT_LT(error, 0.1);
    EXPECT_LT(r.final_rms_px, r.initial_rms_px);
  }
}

TEST(CameraRotationCalibratorTest, RecoversATimeOffsetFromTheUgvsTurning) {
  // The LIO pose of each image is taken 15 ms early: each keyframe's
  // nominal pose is its true one moved back along the camera's motion
  // (1.5 m/s ahead, turning at -15..15 deg/s in turn), on top of a 1 deg
  // mounting rotation.
  const Eigen::Matrix3d correction = Rotation(1.0, {0.3, 1, -0.2});
  const double offset_s = -0.015;
  LScene scene(correction);
  std::vector<Eigen::Vector3d> omega_c, v_wg;
  for (size_t i = 0; i < scene.truth.size(); ++i) {
    // Yaw is about the camera's -y axis (y points down).
    omega_c.push_back(Eigen::Vector3d(0, -1, 0) * (i % 3 == 0 ? 15 : i % 3 == 1 ? -15 : 4) * kDeg);
    v_wg.push_back(1.5 * (scene.truth[i].linear() * Eigen::Vector3d::UnitZ()));
    Pose& T = scene.nominal[i];  // truth * correction^-1, at the true time
    const Eigen::Vector3d w = -omega_c.back() * offset_s;
    T.linear() = T.linear() * Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    T.translation() -= v_wg.back() * offset_s;
  }
  auto observe = [&] {
    auto obs = scene.Observe(3000, 0.5, 0.03, 7);
    for (auto& [key, o] : obs) {
      o.omega_host_c = omega_c[std::get<0>(key)];
      o.v_host_wg = v_wg[std::get<0>(key)];
      o.omega_obs_c = omega_c[std::get<2>(key)];
      o.v_obs_wg = v_wg[std::get<2>(key)];
    }
    return obs;
  };
  CameraRotationCalibrator::Options o;
  o.max_observations = 3000;
  o.estimate_time_offset = true;
  CameraRotationCalibrator with_offset(o);
  o.estimate_time_offset = false;
  CameraRotationCalibrator rotation_only(o);
  for (const auto& [key, obs] : observe()) {
    with_offset.Add(key, obs);
    rotation_only.Add(key, obs);
  }
  const CameraRotationCalibrator::SolveResult r = with_offset.Solve();
  ASSERT_TRUE(r.updated) << r.reason;
  ASSERT_TRUE(rotation_only.Solve().updated);
  const double error = AngleDeg(with_offset.rotation(), correction);
  const double error_rotation_only = AngleDeg(rotation_only.rotation(), correction);
  std::printf(
      "time offset %.2f ms (true %.1f), rotation error %.3f deg (%.3f deg without the "
      "offset), rms %.2f -> %.2f px\n",
      1e3 * with_offset.time_offset_s(), 1e3 * offset_s, error, error_rotation_only,
      r.initial_rms_px, r.final_rms_px);
  EXPECT_NEAR(with_offset.time_offset_s(), offset_s, 0.002);
  EXPECT_LT(error, 0.05);
  EXPECT_EQ(rotation_only.time_offset_s(), 0.0);
  EXPECT_GT(error_rotation_only, error);
}

TEST(CameraRotationCalibratorTest, CountsEachObservationOnceAndRejectsBadOnes) {
  const LScene scene(Rotation(0.5, {0, 1, 0}));
  CameraRotationCalibrator::Options o;
  o.min_observations = 20;
  o.max_observations = 40;
  CameraRotationCalibrator calibrator(o);
  const auto obs = scene.Observe(60, 0.5, 0.0, 9);
  ASSERT_EQ(obs.size(), 60u);

  const CameraRotationCalibrator::SolveResult early = calibrator.Solve();
  EXPECT_FALSE(early.updated);
  EXPECT_NE(early.reason.find("need 20"), std::string::npos) << early.reason;

  EXPECT_TRUE(calibrator.Add(obs[0].first, obs[0].second));
  EXPECT_FALSE(calibrator.Add(obs[0].first, obs[0].second)) << "same key offered again";
  PlaneTrackObservation nan = obs[1].second;
  nan.f_obs.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(calibrator.Add(obs[1].first, nan));
  PlaneTrackObservation grazing = obs[1].second;
  // A plane containing the host ray: no cut.
  const Eigen::Vector3d ray = grazing.T_wg_c_host.linear() * grazing.f_host.homogeneous();
  const Eigen::Vector3d n = ray.cross(Eigen::Vector3d::UnitZ()).normalized();
  grazing.plane << n, -n.dot(grazing.T_wg_c_host.translation());
  EXPECT_FALSE(calibrator.Add(obs[1].first, grazing));
  EXPECT_EQ(calibrator.num_observations(), 1);

  // The kept sample is bounded.
  for (size_t i = 1; i < obs.size(); ++i) calibrator.Add(obs[i].first, obs[i].second);
  EXPECT_EQ(calibrator.num_observations(), 40);
  EXPECT_TRUE(calibrator.Solve().updated);
  // Nothing new: no re-solve.
  EXPECT_FALSE(calibrator.Solve().updated);
}

TEST(CameraRotationCalibratorTest, BadOptionsNameTheKey) {
  CameraRotationCalibrator::Options o;
  o.prior_sigma_deg = 0;
  test::ExpectOptionErrorNaming("prior_sigma_deg", [&] { CameraRotationCalibrator c(o); });
}

}  // namespace
}  // namespace ag
