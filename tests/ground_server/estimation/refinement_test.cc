#include "ground_server/estimation/refinement.h"

#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "ground_server/estimation/cost_functions.h"
#include "tests/support/synthetic_views.h"

namespace ag {
namespace {

using test::LookAt;

Pose Perturb(const Pose& T, std::mt19937& rng, double sigma_t, double sigma_rot) {
  std::normal_distribution<double> n(0, 1);
  Pose d = Pose::Identity();
  d.linear() =
      Eigen::AngleAxisd(sigma_rot * n(rng), Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized())
          .toRotationMatrix();
  d.translation() = sigma_t * Eigen::Vector3d(n(rng), n(rng), n(rng));
  return T * d;
}

// ------------------------------------------------------------ residuals

TEST(CostFunctionTest, ConsistencyResidualIsTheFourDofDifference) {
  // T^ = T_wa_ca * T_ca_wg built to equal a known 4-DoF transform.
  const Pose T_hat = MakePose4Dof(1, 2, 3, 0.4);
  const Pose T_wa_ca = LookAt(Eigen::Vector3d(5, 5, 10), Eigen::Vector3d(0, 0, 0));
  const Pose T_ca_wg = T_wa_ca.inverse() * T_hat;
  RelativePoseConsistencyError f(Eigen::Quaterniond(T_ca_wg.linear()), T_ca_wg.translation(), 1.0,
                                 1.0);
  const Eigen::Quaterniond q(T_wa_ca.linear());
  const double q_a[4] = {q.x(), q.y(), q.z(), q.w()};
  const double t_a[3] = {5, 5, 10};
  double r[4];
  const double same[4] = {1, 2, 3, 0.4};
  ASSERT_TRUE(f(same, q_a, t_a, r));
  for (double v : r) EXPECT_NEAR(v, 0, 1e-12);
  // Off by a yaw of 0.1 rad about the origin: D = RotZ(0.1), t_D = t - RotZ(0.1) t^.
  const Pose T_off = MakePose4Dof(0, 0, 0, 0.1) * T_hat;
  const double off[4] = {T_off.translation().x(), T_off.translation().y(), T_off.translation().z(),
                         0.5};
  ASSERT_TRUE(f(off, q_a, t_a, r));
  const Pose D = T_off * T_hat.inverse();
  EXPECT_NEAR(r[0], D.translation().x(), 1e-12);
  EXPECT_NEAR(r[1], D.translation().y(), 1e-12);
  EXPECT_NEAR(r[2], D.translation().z(), 1e-12);
  EXPECT_NEAR(r[3], 0.1, 1e-12);
}

TEST(CostFunctionTest, ReprojectionResidualsVanishAtTheTruth) {
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  const Pose T_wa_wg = MakePose4Dof(3, -1, 0.5, 0.7);
  const Pose T_wa_ca = LookAt(Eigen::Vector3d(0, 0, 8), Eigen::Vector3d(2, 1, 0));
  const Eigen::Vector3d p_wg = T_wa_wg.inverse() * Eigen::Vector3d(1.5, 0.5, 0.2);
  Eigen::Vector2d uv;
  ASSERT_TRUE(camera.Project(T_wa_ca.inverse() * (T_wa_wg * p_wg), &uv));
  AirGroundReprojectionError f(&camera, p_wg, uv, 1.0);
  const double x[4] = {3, -1, 0.5, 0.7};
  const Eigen::Quaterniond q(T_wa_ca.linear());
  const double q_a[4] = {q.x(), q.y(), q.z(), q.w()};
  const double t_a[3] = {0, 0, 8};
  double r[2];
  ASSERT_TRUE(f(x, q_a, t_a, r));
  EXPECT_NEAR(r[0], 0, 1e-9);
  EXPECT_NEAR(r[1], 0, 1e-9);
  const double x_off[4] = {3.1, -1, 0.5, 0.7};
  ASSERT_TRUE(f(x_off, q_a, t_a, r));
  EXPECT_GT(std::hypot(r[0], r[1]), 1.0);  // 10 cm at ~8 m is several pixels

  // Inverse-depth form: a point at depth 4 in host h, seen in frame j.
  const Pose T_wg_h = LookAt(Eigen::Vector3d(0, 0, 0.5), Eigen::Vector3d(5, 0, 0.5));
  const Pose T_wg_j = LookAt(Eigen::Vector3d(0.5, 0.1, 0.5), Eigen::Vector3d(5, 0, 0.5));
  const Eigen::Vector3d p_h(0.4, -0.2, 4.0);
  Eigen::Vector2d uv_j;
  ASSERT_TRUE(camera.Project(T_wg_j.inverse() * (T_wg_h * p_h), &uv_j));
  InverseDepthReprojectionError g(&camera, p_h.head<2>() / p_h.z(), uv_j, 1.0);
  const Eigen::Quaterniond qh(T_wg_h.linear()), qj(T_wg_j.linear());
  const double qh_xyzw[4] = {qh.x(), qh.y(), qh.z(), qh.w()},
               qj_xyzw[4] = {qj.x(), qj.y(), qj.z(), qj.w()};
  const Eigen::Vector3d th = T_wg_h.translation(), tj = T_wg_j.translation();
  const double rho = 0.25;
  ASSERT_TRUE(g(qh_xyzw, th.data(), qj_xyzw, tj.data(), &rho, r));
  EXPECT_NEAR(r[0], 0, 1e-9);
  EXPECT_NEAR(r[1], 0, 1e-9);
}

// The analytic inverse-depth reprojection against the autodiff functor it
// replaces in stage 1: residuals and all five Jacobians, for both camera
// models, at random poses (quaternions slightly off unit length, as between
// Ceres' manifold steps) and points at 2-40 m.
TEST(CostFunctionTest, AnalyticInverseDepthJacobiansMatchAutodiff) {
  CameraParams fisheye = test::Pinhole640x480({0.01, -0.002, 0.0005, -0.0001});
  fisheye.model = "equidistant";
  const Camera cameras[2] = {Camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005, 0.002})),
                             Camera(fisheye)};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  int compared = 0;
  for (const Camera& camera : cameras) {
    for (int trial = 0; trial < 50; ++trial) {
      const Pose T_h = Perturb(
          LookAt(Eigen::Vector3d(u(rng), u(rng), 0.5), Eigen::Vector3d(10, 3 * u(rng), 0.5)), rng,
          0.1, 0.05);
      const Pose T_j = Perturb(T_h, rng, 0.5, 0.1);
      const double depth = 2 + 19 * (u(rng) + 1);
      const Eigen::Vector2d f_h(0.5 * u(rng), 0.4 * u(rng));
      const Eigen::Vector2d uv(320 + 200 * u(rng), 240 + 150 * u(rng));
      const double sigma = 1.5;
      const Eigen::Quaterniond qh(T_h.linear()), qj(T_j.linear());
      const Eigen::Vector4d q_h = (1 + 0.01 * u(rng)) * qh.coeffs();
      const Eigen::Vector4d q_j = (1 + 0.01 * u(rng)) * qj.coeffs();
      const Eigen::Vector3d t_h = T_h.translation(), t_j = T_j.translation();
      const double rho = 1 / depth;
      const double* params[5] = {q_h.data(), t_h.data(), q_j.data(), t_j.data(), &rho};

      std::unique_ptr<ceres::CostFunction> autodiff(
          InverseDepthReprojectionError::Create(&camera, f_h, uv, sigma));
      const InverseDepthReprojectionCost analytic(&camera, f_h, uv, sigma);
      const int sizes[5] = {4, 3, 4, 3, 1};
      double r_auto[2], r_analytic[2];
      std::vector<std::vector<double>> J_auto(5), J_analytic(5);
      double* ja[5];
      double* jb[5];
      for (int b = 0; b < 5; ++b) {
        J_auto[b].assign(2 * sizes[b], 0);
        J_analytic[b].assign(2 * sizes[b], -1);
        ja[b] = J_auto[b].data();
        jb[b] = J_analytic[b].data();
      }
      const bool ok_auto = autodiff->Evaluate(params, r_auto, ja);
      ASSERT_EQ(analytic.Evaluate(params, r_analytic, jb), ok_auto) << "trial " << trial;
      if (!ok_auto) continue;
      ++compared;
      for (int k = 0; k < 2; ++k) EXPECT_NEAR(r_analytic[k], r_auto[k], 1e-9);
      for (int b = 0; b < 5; ++b) {
        for (size_t k = 0; k < J_auto[b].size(); ++k) {
          EXPECT_NEAR(J_analytic[b][k], J_auto[b][k], 1e-9 * (1 + std::abs(J_auto[b][k])))
              << "block " << b << " entry " << k << " trial " << trial;
        }
      }
      // Residuals alone (no Jacobians requested) are the same too.
      double r_only[2];
      ASSERT_TRUE(analytic.Evaluate(params, r_only, nullptr));
      EXPECT_EQ(r_only[0], r_analytic[0]);
    }
  }
  EXPECT_GE(compared, 90) << "most random points must be in front of the camera";

  // Behind the camera both reject the step.
  const Camera& camera = cameras[0];
  const double q[4] = {0, 0, 0, 1}, t[3] = {0, 0, 0}, t_far[3] = {0, 0, 10}, rho = 0.5;
  const double* params[5] = {q, t, q, t_far, &rho};
  double r[2];
  std::unique_ptr<ceres::CostFunction> autodiff(
      InverseDepthReprojectionError::Create(&camera, Eigen::Vector2d::Zero(), {320, 240}, 1));
  EXPECT_FALSE(autodiff->Evaluate(params, r, nullptr));
  EXPECT_FALSE(InverseDepthReprojectionCost(&camera, Eigen::Vector2d::Zero(), {320, 240}, 1)
                   .Evaluate(params, r, nullptr));
}

TEST(CostFunctionTest, RelativePoseResidualIsZeroForTheMeasuredMotion) {
  std::mt19937 rng(1);
  const Pose A = Perturb(Pose::Identity(), rng, 1.0, 1.0);
  const Pose B = Perturb(A, rng, 1.0, 1.0);
  const Pose T_ab = A.inverse() * B;
  RelativePoseError f(Eigen::Quaterniond(T_ab.linear()), T_ab.translation(), 0.1, 0.01);
  const Eigen::Quaterniond qa(A.linear()), qb(B.linear());
  // -q_b is the same rotation: the residual must not flip.
  const double qa_xyzw[4] = {qa.x(), qa.y(), qa.z(), qa.w()};
  const double qb_xyzw[4] = {-qb.x(), -qb.y(), -qb.z(), -qb.w()};
  double r[6];
  ASSERT_TRUE(f(qa_xyzw, A.translation().data(), qb_xyzw, B.translation().data(), r));
  for (double v : r) EXPECT_NEAR(v, 0, 1e-9);
}

// ------------------------------------------------------------ stage 2

struct AirScene {
  Pose T_wa_wg;
  std::vector<AirFrame> frames;  // VIO poses (noisy)
  std::vector<Pose> true_T_wa_c;
  std::vector<AirGroundObservation> observations;
  std::vector<PairEstimate> pairs;
};

AirScene MakeAirScene(const Camera* camera, uint32_t seed, double noise_px, double vio_noise_t) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> n(0, 1);
  AirScene s;
  s.T_wa_wg = MakePose4Dof(5 * u(rng), 5 * u(rng), u(rng), M_PI * u(rng));
  for (int f = 0; f < 4; ++f) {
    const Eigen::Vector3d target_wg(2 * u(rng), 2 * u(rng), 0);
    const Eigen::Vector3d pos_wg(4 * u(rng), 4 * u(rng), 7 + u(rng));
    const Pose T_true = LookAt(s.T_wa_wg * pos_wg, s.T_wa_wg * target_wg);
    s.true_T_wa_c.push_back(T_true);
    AirFrame frame;
    frame.t_ns = f * 1000000000LL;
    frame.T_wa_c = Perturb(T_true, rng, vio_noise_t, vio_noise_t / 10);
    frame.camera = camera;
    s.frames.push_back(frame);
    for (int k = 0; k < 120; ++k) {
      const Eigen::Vector3d p_wg(target_wg.x() + 4 * u(rng), target_wg.y() + 3 * u(rng),
                                 0.5 * (u(rng) + 1));
      Eigen::Vector2d uv;
      if (!camera->Project(T_true.inverse() * (s.T_wa_wg * p_wg), &uv) || !camera->InImage(uv))
        continue;
      uv += noise_px * Eigen::Vector2d(n(rng), n(rng));
      s.observations.push_back({f, p_wg, uv});
    }
    PairEstimate pair;
    pair.air_frame = f;
    // Each pair's own estimate, off by a few cm / tenths of a degree.
    const Pose T_hat =
        MakePose4Dof(0.03 * n(rng), 0.03 * n(rng), 0.03 * n(rng), 0.005 * n(rng)) * s.T_wa_wg;
    pair.T_ca_wg = frame.T_wa_c.inverse() * T_hat;
    pair.weight = 1.0;
    s.pairs.push_back(pair);
  }
  return s;
}

double TErr(const Pose& a, const Pose& b) { return (a.translation() - b.translation()).norm(); }
double YawErrDeg(const Pose& a, const Pose& b) {
  return std::abs(WrapAngle(ProjectedYaw(a.linear()) - ProjectedYaw(b.linear()))) * 180 / M_PI;
}

TEST(Stage2Test, RecoversKnownPerturbation) {
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  for (uint32_t seed = 0; seed < 5; ++seed) {
    const AirScene s = MakeAirScene(&camera, seed, 0.5, 0.0);
    const Pose initial = MakePose4Dof(0.3, -0.2, 0.1, 0.03) * s.T_wa_wg;
    Stage2Options o;
    const Stage2Result r = RunStage2(initial, s.frames, s.observations, s.pairs, o);
    ASSERT_TRUE(r.success) << r.reason;
    EXPECT_LT(TErr(r.T_wa_wg, s.T_wa_wg), 0.01) << seed;
    EXPECT_LT(YawErrDeg(r.T_wa_wg, s.T_wa_wg), 0.05) << seed;
    EXPECT_LT(r.rms_reprojection_px, 1.0);
    EXPECT_TRUE(r.has_covariance);
  }
}

TEST(Stage2Test, ConsistencyOnlyAveragesPairs) {
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  const AirScene s = MakeAirScene(&camera, 3, 0.5, 0.0);
  Stage2Options o;
  o.use_reprojection = false;
  const Stage2Result r =
      RunStage2(MakePose4Dof(1, 1, 0, 0.2) * s.T_wa_wg, s.frames, {}, s.pairs, o);
  ASSERT_TRUE(r.success) << r.reason;
  // The pairs scatter by 3 cm and 0.3 deg; their mean is within ~2 sigma/sqrt(4).
  EXPECT_LT(TErr(r.T_wa_wg, s.T_wa_wg), 0.06);
  EXPECT_LT(YawErrDeg(r.T_wa_wg, s.T_wa_wg), 0.6);
}

TEST(Stage2Test, CovarianceIsConsistentWithTheError) {
  // NEES over many seeds: with correctly modelled noise its mean is ~4
  // (dimension); an over-confident covariance would give far more.
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  double nees_sum = 0;
  const int trials = 30;
  for (uint32_t seed = 0; seed < trials; ++seed) {
    const AirScene s = MakeAirScene(&camera, 1000 + seed, 1.0, 0.0);
    Stage2Options o;
    o.use_consistency = false;  // only the modelled pixel noise
    const Stage2Result r = RunStage2(s.T_wa_wg, s.frames, s.observations, {}, o);
    ASSERT_TRUE(r.success && r.has_covariance);
    Eigen::Vector4d e;
    e.head<3>() = r.T_wa_wg.translation() - s.T_wa_wg.translation();
    e(3) = WrapAngle(ProjectedYaw(r.T_wa_wg.linear()) - ProjectedYaw(s.T_wa_wg.linear()));
    nees_sum += e.dot(r.covariance.ldlt().solve(e));
  }
  const double mean_nees = nees_sum / trials;
  std::printf("mean NEES over %d trials: %.2f (dimension 4)\n", trials, mean_nees);
  EXPECT_GT(mean_nees, 1.5);
  EXPECT_LT(mean_nees, 8.0);
}

TEST(Stage2Test, FailsWithoutMeasurements) {
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  const AirScene s = MakeAirScene(&camera, 1, 0.5, 0.0);
  Stage2Options o;
  o.use_consistency = false;
  const Stage2Result r = RunStage2(s.T_wa_wg, s.frames, {}, {}, o);
  EXPECT_FALSE(r.success);
  EXPECT_FALSE(r.reason.empty());
}

// ------------------------------------------------------------ stage 1

TEST(Stage1Test, RecoversPerturbedUgvPoses) {
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> n(0, 1);
  // UGV drives along x at 0.5 m height looking forward at a wall at x = 8.
  std::vector<Pose> truth;
  std::vector<UgvWindowFrame> frames;
  for (int i = 0; i < 5; ++i) {
    const Eigen::Vector3d pos(0.4 * i, 0.1 * u(rng), 0.5);
    truth.push_back(LookAt(pos, pos + Eigen::Vector3d(1, 0.05 * u(rng), 0)));
    UgvWindowFrame f;
    f.t_ns = i * 100000000LL;
    f.camera = &camera;
    // Interpolation / time-offset error: a few cm and tenths of a degree.
    f.T_wg_c = i == 0 ? truth[0] : Perturb(truth[i], rng, 0.03, 0.005);
    frames.push_back(f);
  }
  std::vector<UgvTrack> tracks;
  std::vector<Eigen::Vector3d> true_points;
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d p(8.0 + 0.3 * u(rng), 4 * u(rng), 0.5 + 1.5 * u(rng));
    UgvTrack t;
    t.host_frame = 0;
    const Eigen::Vector3d p_h = truth[0].inverse() * p;
    t.f_host = p_h.head<2>() / p_h.z();
    t.lidar_depth = p_h.z() + 0.02 * n(rng);
    for (int j = 1; j < 5; ++j) {
      Eigen::Vector2d uv;
      if (camera.Project(truth[j].inverse() * p, &uv) && camera.InImage(uv)) {
        t.observations.emplace_back(j, uv + 0.3 * Eigen::Vector2d(n(rng), n(rng)));
      }
    }
    if (t.observations.empty()) continue;
    tracks.push_back(t);
    true_points.push_back(p);
  }
  Stage1Options o;
  o.lio_sigma_t_m = 0.05;  // the perturbation above is not LIO-consistent
  o.lio_sigma_rot_deg = 0.5;
  const Stage1Result r = RunStage1(frames, tracks, o);
  ASSERT_TRUE(r.success) << r.reason;
  EXPECT_LT(r.final_cost, r.initial_cost);
  for (int i = 1; i < 5; ++i) {
    const double before = TErr(frames[i].T_wg_c, truth[i]);
    const double after = TErr(r.T_wg_c[i], truth[i]);
    EXPECT_LT(after, 0.5 * before + 0.005) << "frame " << i;
    const double rot_after =
        Eigen::AngleAxisd(r.T_wg_c[i].linear().transpose() * truth[i].linear()).angle();
    EXPECT_LT(rot_after * 180 / M_PI, 0.1) << "frame " << i;
  }
  double worst = 0;
  for (size_t k = 0; k < tracks.size(); ++k)
    worst = std::max(worst, (r.points_wg[k] - true_points[k]).norm());
  EXPECT_LT(worst, 0.1);
}

TEST(Stage1Test, MapAnchoringCorrectsAConstantCameraMountError) {
  // The whole window's camera is off by the same 1 deg / 2 cm (extrinsic
  // error): the oldest-pose gauge would keep it; anchoring points to the
  // map's planes (ground, and walls at x = 8 and y = 4) removes it.
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> n(0, 1);
  Pose mount_error = Pose::Identity();
  mount_error.linear() =
      Eigen::AngleAxisd(1.0 * M_PI / 180, Eigen::Vector3d(0.3, 1.0, 0.5).normalized())
          .toRotationMatrix();
  mount_error.translation() = Eigen::Vector3d(0.01, -0.015, 0.005);
  std::vector<Pose> truth;
  std::vector<UgvWindowFrame> frames;
  for (int i = 0; i < 5; ++i) {
    const Eigen::Vector3d pos(0.5 * i, 0.3 * i, 0.5);
    truth.push_back(LookAt(pos, Eigen::Vector3d(8, 2.5 + 0.2 * i, 0.3)));
    frames.push_back({i * 500000000LL, truth.back() * mount_error, &camera});
  }
  const std::vector<Eigen::Vector4d> planes = {
      {0, 0, 1, 0}, {1, 0, 0, -8}, {0, 1, 0, -4}};  // n.p + d = 0
  std::vector<UgvTrack> tracks;
  for (int k = 0; k < 300; ++k) {
    const int plane = k % 3;
    Eigen::Vector3d p;
    if (plane == 0) p = {2 + 5 * (u(rng) + 1) / 2, 2.5 * (u(rng) + 1) / 2, 0};
    if (plane == 1) p = {8, 2 * u(rng) + 2, 1.5 * (u(rng) + 1)};
    if (plane == 2) p = {4 + 3.5 * (u(rng) + 1) / 2, 4, 1.5 * (u(rng) + 1)};
    UgvTrack t;
    t.host_frame = k % 5;
    const Eigen::Vector3d p_h = truth[t.host_frame].inverse() * p;
    Eigen::Vector2d uv_h;
    if (p_h.z() < 0.5 || !camera.Project(p_h, &uv_h) || !camera.InImage(uv_h)) continue;
    t.f_host = p_h.head<2>() / p_h.z();
    // What depth association gives: the map along the (wrong) ray.
    const Pose& T_h = frames[t.host_frame].T_wg_c;
    const Eigen::Vector3d ray = T_h.linear() * Eigen::Vector3d(t.f_host.x(), t.f_host.y(), 1);
    const Eigen::Vector4d& pl = planes[plane];
    t.lidar_depth = -(pl.head<3>().dot(T_h.translation()) + pl[3]) / pl.head<3>().dot(ray);
    if (!(t.lidar_depth > 0.5)) continue;
    t.plane = pl;
    for (int j = 0; j < 5; ++j) {
      Eigen::Vector2d uv;
      if (j != t.host_frame && camera.Project(truth[j].inverse() * p, &uv) && camera.InImage(uv)) {
        t.observations.emplace_back(j, uv + 0.3 * Eigen::Vector2d(n(rng), n(rng)));
      }
    }
    if (!t.observations.empty()) tracks.push_back(t);
  }
  ASSERT_GT(tracks.size(), 100u);
  auto rot_err_deg = [](const Pose& a, const Pose& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180 / M_PI;
  };
  Stage1Options o;
  const Stage1Result anchored = RunStage1(frames, tracks, o);
  ASSERT_TRUE(anchored.success) << anchored.reason;
  EXPECT_TRUE(anchored.anchored_to_map);
  EXPECT_EQ(anchored.plane_tracks, static_cast<int>(tracks.size()));
  o.anchor_to_map = false;
  const Stage1Result held = RunStage1(frames, tracks, o);
  ASSERT_TRUE(held.success) << held.reason;
  EXPECT_FALSE(held.anchored_to_map);
  for (int i = 0; i < 5; ++i) {
    EXPECT_LT(rot_err_deg(anchored.T_wg_c[i], truth[i]), 0.1) << "frame " << i;
    EXPECT_LT(TErr(anchored.T_wg_c[i], truth[i]), 0.01) << "frame " << i;
    EXPECT_GT(rot_err_deg(held.T_wg_c[i], truth[i]), 0.5) << "frame " << i;
  }
}

TEST(Stage1Test, NeedsTwoFramesAndTracks) {
  const Camera camera(test::Pinhole640x480({-0.05, 0.01, 0.001, -0.0005}));
  std::vector<UgvWindowFrame> frames(1);
  frames[0].camera = &camera;
  EXPECT_FALSE(RunStage1(frames, {}, {}).success);
  frames.resize(2, frames[0]);
  const Stage1Result r = RunStage1(frames, {}, {});
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.reason.find("no UGV track"), std::string::npos);
}

}  // namespace
}  // namespace ag
