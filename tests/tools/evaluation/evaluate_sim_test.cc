// The whole estimator, end to end on the simulator's `small` scenario
// (lengthened to get several estimates): fixes arrive, they are accurate,
// their covariance is consistent with their actual error, and no false fix
// is published, also where the UAV never sees what the UGV sees.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "common/dataset/dataset.h"
#include "tests/support/test_support.h"
#include "tools/evaluation/evaluator.h"
#include "tools/sim/scenario.h"
#include "tools/sim/simulator.h"

namespace ag {
namespace {

// `small`, seed 3, lengthened to 9 s; no depth images (not needed here).
Scenario SmallScenario(double duration_s) {
  Scenario s = LoadScenario(test::SourceDir() + "/config/scenarios/small.yaml");
  s.options.duration_s = duration_s;
  s.options.ground.camera.depth = false;
  for (auto& [name, air] : s.air) air.camera.depth = false;
  return s;
}

EvaluateOptions XFeatOptions(const std::string& model) {
  EvaluateOptions o;
  o.features.model_path = model;
  return o;
}

TEST(EvaluateSim, SmallScenarioFixesAreAccurateConsistentAndNeverFalse) {
  AG_REQUIRE_SHARED(model, "models/xfeat.onnx");
  test::TempDir tmp;
  Simulation(SmallScenario(9.0), 3).Write(tmp / "ds");
  const EvaluationResult result = Evaluate(ReadDataset(tmp / "ds"), XFeatOptions(model));
  const nlohmann::json& agent = result.report["agents"]["uav1"];
  SCOPED_TRACE(agent.dump(1));

  // Keyframes at 1 Hz, a fix after three agreeing estimates: from ~4 s on.
  EXPECT_GE(agent["fixes"].get<int>(), 4);
  EXPECT_EQ(agent["false_fixes"].get<int>(), 0);
  // Stage 1's run-long camera rotation: the UGV camera is ~1 deg and 15 ms
  // off its nominal calibration against the LiDAR map; the plane-cut
  // estimate must remove most of the rotation within these 9 s.
  const double nominal = agent["ugv_camera_rotation_error_deg"]["nominal"].get<double>();
  const double corrected = agent["ugv_camera_rotation_error_deg"]["stage1"].get<double>();
  std::printf("UGV camera rotation against the map: %.3f deg nominal, %.3f deg after stage 1\n",
              nominal, corrected);
  EXPECT_GT(nominal, 0.3) << "the scenario should have a mounting error to correct";
  EXPECT_LT(corrected, 0.5 * nominal);
  // Its position error is reported too; the calibrator corrects only the
  // rotation (estimating the position made the fixes worse, tools/evaluation/ACCURACY.md), so it
  // stays as nominal.
  const double shift = agent["ugv_camera_translation_error_m"]["nominal"].get<double>();
  EXPECT_GT(shift, 0.005) << "the scenario should have a camera position error";
  EXPECT_NEAR(agent["ugv_camera_translation_error_m"]["stage1"].get<double>(), shift, 1e-9);
  const double true_offset = agent["ugv_camera_time_offset_ms"]["true"].get<double>();
  const double offset = agent["ugv_camera_time_offset_ms"]["estimated"].get<double>();
  std::printf("UGV camera time offset against LIO: true %.1f ms, estimated %.1f ms\n", true_offset,
              offset);
  // The same observations give the camera's time offset (15 ms-ish in the
  // simulator): within 9 s it must have the right sign and more than half
  // of it (9.9 of 13.3 ms when written), so the poses it corrects are
  // nearer the truth than with none.
  EXPECT_GT(std::abs(true_offset), 5.0) << "the scenario should have a time offset to estimate";
  EXPECT_GT(offset * true_offset, 0.0) << "wrong sign";
  EXPECT_LT(std::abs(offset - true_offset), 0.5 * std::abs(true_offset));
  // Bounds from what this pipeline achieves here (tools/evaluation/ACCURACY.md): at
  // the 10-25 m of the matched structure the rest of the calibration error
  // is 5-35 cm. These bounds fail on a regression of matching, RANSAC or
  // refinement (without stage 1 the median yaw error here is 0.65 deg), not
  // on the known calibration limit.
  EXPECT_LT(agent["translation_error_m"]["median"].get<double>(), 0.2);
  EXPECT_LT(agent["yaw_error_deg"]["median"].get<double>(), 0.6);
  EXPECT_LT(agent["translation_error_m"]["max"].get<double>(), 0.5);
  EXPECT_LT(agent["final"]["yaw_error_deg"].get<double>(), 1.0);
  // Where the vehicles are (a few metres from the ground world's origin
  // here) the fix is as good as its translation.
  EXPECT_LT(agent["drift_free"]["translation_error_at_ugv_m"]["median"].get<double>(), 0.2);

  // Consistency (NEES): for a consistent 4-DoF covariance the mean of
  // e^T P^-1 e over estimates is 4. Too large: overconfident.
  double nees_sum = 0;
  int n = 0;
  for (const EstimateLog& e : result.estimates.at("uav1")) {
    if (!e.published || !e.has_covariance || !e.drift_free_residual) continue;
    const Eigen::Vector4d r = *e.drift_free_residual;
    nees_sum += r.dot(e.covariance.ldlt().solve(r));
    ++n;
  }
  ASSERT_GE(n, 3);
  const double nees = nees_sum / n;
  RecordProperty("mean_nees", std::to_string(nees));
  EXPECT_LT(nees, 3 * 4.0) << "covariance overconfident: mean NEES " << nees;
  EXPECT_GT(nees, 4.0 / 50) << "covariance uselessly pessimistic: mean NEES " << nees;

  // The per-estimate CSV: one row per estimate, published ones as many as
  // the fixes, with their drift-free residuals.
  const Dataset dataset = ReadDataset(tmp / "ds");
  WriteTrajectoryOutputs(dataset, result, tmp / "out_", false);
  std::ifstream csv(tmp / "out_uav1_estimates.csv");
  ASSERT_TRUE(csv.good());
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line.rfind("# ", 0), 0u) << line;
  std::getline(csv, line);
  EXPECT_EQ(line.rfind("t_s,success,published,x,y,z,yaw_deg,", 0), 0u) << line;
  size_t rows = 0;
  EXPECT_NE(line.find(",time_ms,stage1_ms,air_keyframes,reason"), std::string::npos) << line;
  int published = 0, with_residual = 0;
  while (std::getline(csv, line)) {
    ++rows;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    ASSERT_GE(cells.size(), 18u) << line;
    published += cells[2] == "1";
    with_residual += !cells[14].empty();
    if (cells[1] == "1") {
      ASSERT_GE(cells.size(), 24u) << line;
      EXPECT_GT(std::stod(cells[21]), 0.0) << "an estimate has its time: " << line;
      EXPECT_LE(std::stod(cells[22]), std::stod(cells[21])) << "stage 1 is part of it: " << line;
      EXPECT_FALSE(cells[23].empty()) << "an estimate names its UAV keyframes: " << line;
    }
  }
  EXPECT_EQ(rows, result.estimates.at("uav1").size());
  EXPECT_EQ(published, agent["fixes"].get<int>());
  EXPECT_GE(with_residual, published);
}

TEST(EvaluateSim, NoFalseFixWhenTheUavNeverSeesTheUgvArea) {
  AG_REQUIRE_SHARED(model, "models/xfeat.onnx");
  // The same world; the UAV circles a far corner, facing away from the
  // UGV's circle.
  Scenario s = SmallScenario(8.0);
  AirAgentOptions& uav = s.air.begin()->second;
  uav.path.center = {15.0, -15.0};
  uav.path.radius_m = 3.0;
  uav.path.heading = "tangent";
  uav.path.yaw_deg = 90.0;  // outwards
  test::TempDir tmp;
  Simulation(s, 3).Write(tmp / "ds");
  const EvaluationResult result = Evaluate(ReadDataset(tmp / "ds"), XFeatOptions(model));
  const nlohmann::json& agent = result.report["agents"]["uav1"];
  SCOPED_TRACE(agent.dump(1));
  EXPECT_EQ(agent["false_fixes"].get<int>(), 0);
  for (const EstimateLog& e : result.estimates.at("uav1")) {
    if (e.published) {
      ASSERT_TRUE(e.error.has_value());
      EXPECT_LT(e.error->translation_m, 1.0);
    }
  }
}

TEST(EvaluateSim, SplitKeyframesKeepFixingOnALossyLink) {
  AG_REQUIRE_SHARED(model, "models/xfeat.onnx");
  test::TempDir tmp;
  Simulation(SmallScenario(9.0), 3).Write(tmp / "ds");
  const Dataset dataset = ReadDataset(tmp / "ds");
  // 10% of the IP packets lost: a whole 1024-keypoint keyframe (~52
  // packets) crosses 0.4% of the time, one part of one packet 90%.
  EvaluateOptions whole = XFeatOptions(model);
  whole.link_loss = 0.1;
  EvaluateOptions split = whole;
  split.air.max_part_bytes = 1500;
  const nlohmann::json w = Evaluate(dataset, whole).report["agents"]["uav1"];
  const nlohmann::json p = Evaluate(dataset, split).report["agents"]["uav1"];
  std::printf("10%% loss: whole keyframes: %s, %d fixes; split: %s, %d fixes\n",
              w["link"].dump().c_str(), w["fixes"].get<int>(), p["link"].dump().c_str(),
              p["fixes"].get<int>());
  for (const nlohmann::json* a : {&w, &p}) {
    const double lost =
        (*a)["link"]["ip_packets_lost"].get<double>() / (*a)["link"]["ip_packets"].get<double>();
    EXPECT_NEAR(lost, 0.1, 0.03) << a->dump(1);
    EXPECT_EQ((*a)["false_fixes"].get<int>(), 0);
  }
  const int sent = p["packets_sent"].get<int>();  // keyframes
  EXPECT_LE(w["link"]["keyframes_stored"].get<int>(), 1);
  EXPECT_EQ(w["fixes"].get<int>(), 0);
  EXPECT_GE(p["link"]["keyframes_stored"].get<int>(), sent - 1);
  EXPECT_GT(p["link"]["keypoints_stored"].get<int>(), sent * 1024 * 8 / 10);
  EXPECT_GE(p["fixes"].get<int>(), 2);  // 3 measured (4 or more without loss)
  EXPECT_LT(p["translation_error_m"]["median"].get<double>(), 0.2);
}

}  // namespace
}  // namespace ag
