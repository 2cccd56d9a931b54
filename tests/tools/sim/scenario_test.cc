#include "tools/sim/scenario.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>

#include "tests/support/test_support.h"
#include "tools/sim/simulator.h"

namespace ag {
namespace {

constexpr double kDeg = M_PI / 180.0;

std::string Preset(const std::string& name) {
  return test::SourceDir() + "/config/scenarios/" + name + ".yaml";
}

TEST(SimScenario, PresetsLoad) {
  for (const char* name : {"small", "covisible", "no_initial_covisibility", "multi_uav"}) {
    const Scenario s = LoadScenario(Preset(name));
    EXPECT_EQ(s.options.name, name);
    EXPECT_FALSE(s.air.empty());
  }
  EXPECT_EQ(LoadScenario(Preset("multi_uav")).air.size(), 3u);
  EXPECT_DOUBLE_EQ(LoadScenario(Preset("covisible")).options.duration_s, 60.0);
}

TEST(SimScenario, UnknownKeysAndBadValuesAreRejectedWithFileAndLine) {
  test::TempDir dir;
  auto write = [&](const std::string& text) {
    std::ofstream(dir / "s.yaml") << text;
    return dir / "s.yaml";
  };
  try {
    LoadScenario(write("name: x\nground:\n  camera:\n    fxx: 3\nair:\n  uav1: {}\n"));
    FAIL() << "unknown key accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), InputErrorKind::kUnknownKey);
    EXPECT_EQ(e.line(), 4);
    EXPECT_NE(std::string(e.what()).find("ground.camera.fxx"), std::string::npos) << e.what();
  }
  try {
    LoadScenario(write("air:\n  uav1:\n    altitude_m: 500\n"));
    FAIL() << "bad altitude accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), InputErrorKind::kBadValue);
    EXPECT_NE(std::string(e.what()).find("altitude_m"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LoadScenario(write("air:\n  UAV-1: {}\n")), InputError);
  EXPECT_THROW(LoadScenario(write("name: no air\n")), InputError);
  EXPECT_THROW(LoadScenario(write("air:\n  uav1:\n    path: {shape: spiral}\n")), InputError);
}

TEST(SimScenario, TrueCalibrationDiffersFromNominalByTheConfiguredAmounts) {
  const Scenario scenario = LoadScenario(Preset("covisible"));
  const CalibrationErrorOptions& e = scenario.options.ground.calibration_error;
  for (uint64_t seed : {1u, 2u, 3u, 4u}) {
    const Simulation sim(scenario, seed);
    const SimAgent& g = sim.ground();
    for (const auto& [nominal, truth] :
         {std::make_pair(g.T_body_camera_nominal, g.T_body_camera_true),
          std::make_pair(g.T_body_lidar_nominal, g.T_body_lidar_true)}) {
      const Pose delta = nominal.inverse() * truth;
      const double angle = Eigen::AngleAxisd(delta.linear()).angle() / kDeg;
      EXPECT_GE(angle, e.rotation_min_deg - 1e-9);
      EXPECT_LE(angle, e.rotation_max_deg + 1e-9);
      EXPECT_GE(delta.translation().norm(), e.translation_min_m - 1e-12);
      EXPECT_LE(delta.translation().norm(), e.translation_max_m + 1e-12);
    }
    const double dt = std::fabs(g.camera_offset_true_s - g.camera_offset_nominal_s);
    EXPECT_GE(dt, e.time_offset_min_s - 1e-12);
    EXPECT_LE(dt, e.time_offset_max_s + 1e-12);
    // Each air world differs from the ground world by a 4-DoF transform.
    for (size_t a = 1; a < sim.agents().size(); ++a) {
      const Pose T_wa_wg = sim.agents()[a]->T_W_world.inverse() * g.T_W_world;
      EXPECT_NEAR(T_wa_wg.linear()(2, 2), 1.0, 1e-12);
      EXPECT_NEAR(T_wa_wg.linear().row(2).head<2>().norm(), 0.0, 1e-12);
    }
  }
}

TEST(SimScenario, ErrorScalesShrinkOneSensorsMountingErrorOnly) {
  Scenario scenario = LoadScenario(Preset("covisible"));
  const Simulation reference(scenario, 3);
  scenario.options.ground.camera_error_scale = 0.0;
  scenario.options.ground.lidar_error_scale = 0.5;
  const Simulation scaled(scenario, 3);
  const SimAgent& r = reference.ground();
  const SimAgent& s = scaled.ground();
  auto angle_deg = [](const Pose& d) { return Eigen::AngleAxisd(d.linear()).angle() / kDeg; };
  // The camera's mounting is exact; its time offset error stays.
  EXPECT_TRUE(s.T_body_camera_true.isApprox(s.T_body_camera_nominal, 1e-15));
  EXPECT_EQ(s.camera_offset_true_s, r.camera_offset_true_s);
  // The LiDAR's error is the same draw at half the size.
  const Pose dr = r.T_body_lidar_nominal.inverse() * r.T_body_lidar_true;
  const Pose ds = s.T_body_lidar_nominal.inverse() * s.T_body_lidar_true;
  EXPECT_GT(angle_deg(dr), 0.4);
  EXPECT_NEAR(angle_deg(ds), 0.5 * angle_deg(dr), 1e-9);
  EXPECT_NEAR(
      (Eigen::AngleAxisd(ds.linear()).axis() - Eigen::AngleAxisd(dr.linear()).axis()).norm(), 0.0,
      1e-9);
  EXPECT_TRUE(ds.translation().isApprox(0.5 * dr.translation(), 1e-12));

  scenario.options.ground.lidar_error_scale = -1.0;
  EXPECT_THROW(scenario.options.ground.Check(), std::exception);
}

TEST(SimScenario, AgentsMoveSmoothlyAtTheirSpeedAndHeight) {
  const Scenario scenario = LoadScenario(Preset("covisible"));
  const Simulation sim(scenario, 1);
  const SimAgent& g = sim.ground();
  const double v = scenario.options.ground.path.speed_mps;
  for (double t = 5.0; t < 55.0; t += 1.0) {
    const Pose a = g.motion->BodyPose(t), b = g.motion->BodyPose(t + 0.01);
    EXPECT_NEAR((b.translation() - a.translation()).head<2>().norm() / 0.01, v, 0.02 * v)
        << "t " << t;
    EXPECT_NEAR(a.translation().z(), scenario.options.ground.body_height_m, 0.01);
    // The UGV faces where it drives.
    const Eigen::Vector3d forward = a.linear().col(0);
    const Eigen::Vector3d motion = (b.translation() - a.translation()).normalized();
    EXPECT_GT(forward.dot(motion), 0.99);
  }
  const SimAgent& air = *sim.agents()[1];
  const double altitude = scenario.air.at("uav1").altitude_m;
  for (double t = 0.0; t < 60.0; t += 2.0) {
    const Pose T = air.motion->BodyPose(t);
    EXPECT_NEAR(T.translation().z(), altitude, scenario.air.at("uav1").altitude_variation_m + 1e-9);
    // Camera pitched down as configured (plus the body's small tilt).
    const Eigen::Vector3d optical_axis = (T * air.T_body_camera_true).linear().col(2);
    const double down = std::asin(-optical_axis.z()) / kDeg;
    EXPECT_NEAR(down, scenario.air.at("uav1").camera.pitch_down_deg, 5.0);
  }
}

}  // namespace
}  // namespace ag
