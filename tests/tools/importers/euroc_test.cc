// tools/import_euroc on a small EuRoC-layout fixture written here (a few
// synthetic PNGs, sensor.yaml in EuRoC's own text, a ground-truth CSV with
// all 17 columns): calibration equal to sensor.yaml, trajectory exact, the
// dataset valid, groundtruth.yaml edited only when asked, failures leave the
// dataset as it was. One test runs the import_euroc binary.

#include "tools/importers/euroc.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/core/error.h"
#include "common/dataset/dataset.h"
#include "common/geometry/tum_io.h"
#include "common/pcd/pcd_io.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

void WriteText(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// EuRoC MH_01_easy's cam0 sensor.yaml, as distributed.
constexpr const char* kSensorYaml = R"(# General sensor definitions.
sensor_type: camera
comment: VI-Sensor cam0 (MT9M034)

# Sensor extrinsics wrt. the body-frame.
T_BS:
  cols: 4
  rows: 4
  data: [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,
         0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,
        -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,
         0.0, 0.0, 0.0, 1.0]

# Camera specific definitions.
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
)";

constexpr int64_t kT0 = 1403636579763555584;  // MH_01's first cam0 time
constexpr int64_t kImageStep = 50000000;      // 20 Hz
constexpr int64_t kPoseStep = 5000000;        // 200 Hz
constexpr int kImages = 6;

struct GtRow {
  int64_t t_ns;
  double p[3];
  double q[4];  // w x y z, as in the file (not exactly unit: 9-10 digits)
};

std::vector<GtRow> GroundTruthRows() {
  std::vector<GtRow> rows;
  // Starts 1.5 image periods after the first image, as EuRoC's ground truth
  // starts after its cameras.
  for (int i = 0; i < 60; ++i) {
    const double s = 0.01 * i;
    const Eigen::Quaterniond q(
        Eigen::AngleAxisd(0.3 + s, Eigen::Vector3d(0.2, -0.1, 1).normalized()));
    GtRow row{kT0 + 3 * kImageStep / 2 + i * kPoseStep,
              {4.688319 + s, -1.786938 - 0.5 * s, 0.783338 + 0.1 * s},
              {q.w(), q.x(), q.y(), q.z()}};
    for (double& c : row.q) c = std::round(c * 1e9) / 1e9;  // the file's precision
    rows.push_back(row);
  }
  return rows;
}

/// A EuRoC sequence folder: mav0/cam0 (sensor.yaml, data.csv, 6 PNGs) and
/// mav0/state_groundtruth_estimate0/data.csv.
std::string WriteEurocFixture(const std::string& root) {
  const std::string cam = root + "/mav0/cam0";
  WriteText(cam + "/sensor.yaml", kSensorYaml);
  std::string csv = "#timestamp [ns],filename\r\n";  // EuRoC's files have CRLF
  fs::create_directories(cam + "/data");
  for (int i = 0; i < kImages; ++i) {
    const int64_t t = kT0 + i * kImageStep;
    csv += std::to_string(t) + "," + std::to_string(t) + ".png\r\n";
    cv::imwrite(cam + "/data/" + std::to_string(t) + ".png",
                cv::Mat(480, 752, CV_8UC1, cv::Scalar(10 * i)));
  }
  WriteText(cam + "/data.csv", csv);
  std::string gt =
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
      "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
      "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
      "b_a_RS_S_z [m s^-2]\n";
  for (const GtRow& r : GroundTruthRows()) {
    char line[512];
    std::snprintf(line, sizeof(line),
                  "%lld,%.17g,%.17g,%.17g,%.9f,%.9f,%.9f,%.9f,0.1,0.2,0.3,-0.002,0.02,0.07,-0.01,"
                  "0.1,0.07\n",
                  static_cast<long long>(r.t_ns), r.p[0], r.p[1], r.p[2], r.q[0], r.q[1], r.q[2],
                  r.q[3]);
    gt += line;
  }
  WriteText(root + "/mav0/state_groundtruth_estimate0/data.csv", gt);
  return root;
}

/// A small valid dataset with a ground agent only.
void WriteGroundDataset(const std::string& dir) {
  DatasetWriter writer(dir, "ground only", "fixture");
  AgentCalibration calibration;
  calibration.camera.camera = {"pinhole", 64, 48, 50, 50, 32, 24, {}};
  calibration.lidar = LidarCalibration{};
  writer.BeginGround(calibration);
  std::vector<StampedPose> odometry;
  for (int i = 0; i < 3; ++i) {
    const int64_t t = 1000000000LL + i * 100000000LL;
    cv::imwrite(writer.AddImage("ground", t), cv::Mat(48, 64, CV_8UC1, cv::Scalar(i)));
    PointCloud cloud;
    cloud.points = {Eigen::Vector3f(1, 2, 3 + i)};
    WriteScan(writer.AddScan(t), cloud);
    odometry.push_back({t, MakePose4Dof(i, 0, 0, 0)});
  }
  writer.SetOdometry("ground", odometry);
  writer.Finish();
}

void ExpectCalibrationOfFixture(const AgentCalibration& c) {
  EXPECT_EQ(c.camera.camera.model, "pinhole");
  EXPECT_EQ(c.camera.camera.width, 752);
  EXPECT_EQ(c.camera.camera.height, 480);
  EXPECT_EQ(c.camera.camera.fx, 458.654);
  EXPECT_EQ(c.camera.camera.fy, 457.296);
  EXPECT_EQ(c.camera.camera.cx, 367.215);
  EXPECT_EQ(c.camera.camera.cy, 248.375);
  EXPECT_EQ(c.camera.camera.distortion,
            (std::vector<double>{-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05}));
  Eigen::Matrix4d T_BS;
  T_BS << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008,
      0.0149672133247, 0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797,
      0.999660727178, 0.00981073058949, 0.0, 0.0, 0.0, 1.0;
  // Equal up to the re-orthonormalisation of a 12-digit rotation.
  EXPECT_LT((c.camera.T_body_camera.matrix() - T_BS).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_EQ(c.camera.T_body_camera.translation(), Eigen::Vector3d(T_BS.topRightCorner<3, 1>()));
  EXPECT_EQ(c.camera.time_offset_s, 0.0);
  EXPECT_FALSE(c.lidar.has_value());
}

void ExpectTrajectoryOfFixture(const std::vector<StampedPose>& poses) {
  const std::vector<GtRow> rows = GroundTruthRows();
  ASSERT_EQ(poses.size(), rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    const GtRow& r = rows[i];
    EXPECT_EQ(poses[i].t_ns, r.t_ns);
    EXPECT_EQ(poses[i].T.translation(), Eigen::Vector3d(r.p[0], r.p[1], r.p[2])) << i;
    const Eigen::Quaterniond q = Eigen::Quaterniond(r.q[0], r.q[1], r.q[2], r.q[3]).normalized();
    EXPECT_LT((poses[i].T.linear() - q.toRotationMatrix()).cwiseAbs().maxCoeff(), 1e-12) << i;
  }
}

TEST(EurocReaders, SensorYamlAndGroundTruth) {
  test::TempDir dir;
  WriteEurocFixture(dir / "MH_01_easy");
  ExpectCalibrationOfFixture(ReadEurocCamera(dir / "MH_01_easy/mav0/cam0/sensor.yaml"));
  ExpectTrajectoryOfFixture(
      ReadEurocGroundTruth(dir / "MH_01_easy/mav0/state_groundtruth_estimate0/data.csv"));
  EXPECT_EQ(FindEurocMav(dir / "MH_01_easy"), dir / "MH_01_easy/mav0");
  EXPECT_EQ(FindEurocMav(dir / "MH_01_easy/mav0"), dir / "MH_01_easy/mav0");
  EXPECT_THROW(FindEurocMav(dir.path()), InputError);
}

TEST(EurocReaders, EquidistantModelAndErrors) {
  test::TempDir dir;
  const std::string path = dir / "sensor.yaml";
  std::string text = kSensorYaml;
  const auto replace = [](std::string s, const std::string& from, const std::string& to) {
    return s.replace(s.find(from), from.size(), to);
  };
  WriteText(path, replace(text, "radial-tangential", "equidistant"));
  EXPECT_EQ(ReadEurocCamera(path).camera.camera.model, "equidistant");

  const auto expect_error = [&](const std::string& yaml, InputErrorKind kind, int64_t line) {
    WriteText(path, yaml);
    try {
      ReadEurocCamera(path);
      ADD_FAILURE() << "no error for:\n" << yaml;
    } catch (const InputError& e) {
      EXPECT_EQ(e.kind(), kind) << e.what();
      EXPECT_EQ(e.file(), path) << e.what();
      EXPECT_EQ(e.line(), line) << e.what();
    }
  };
  expect_error(replace(text, "radial-tangential", "fov"), InputErrorKind::kBadValue, 19);
  expect_error(replace(text, "[752, 480]", "[752]"), InputErrorKind::kMalformedRow, 16);
  expect_error(replace(text, "0.0148655429818,", "0.5,"), InputErrorKind::kNotRotation, 9);
  expect_error(replace(text, "458.654", "nan"), InputErrorKind::kNonFinite, 18);
  expect_error(replace(text, "camera_model: pinhole\n", ""), InputErrorKind::kMissingField, 0);

  const std::string csv = dir / "data.csv";
  WriteText(csv, "#t\n1,0,0,0,1,0,0,0\n2,0,0,0,1,0,0\n");
  EXPECT_THROW(ReadEurocGroundTruth(csv), InputError);
  try {
    ReadEurocGroundTruth(csv);
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
  }
  WriteText(csv, "1,0,0,0,1,0,0,0\n1,0,0,0,1,0,0,0\n");
  try {
    ReadEurocGroundTruth(csv);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), InputErrorKind::kUnsorted);
    EXPECT_EQ(e.line(), 2);
  }
  WriteText(csv, "1,0,0,0,0.5,0,0,0\n");
  EXPECT_THROW(ReadEurocGroundTruth(csv), InputError);
}

TEST(EurocImport, IntoAnExistingDataset) {
  test::TempDir dir;
  WriteEurocFixture(dir / "MH_01_easy");
  WriteGroundDataset(dir / "ds");
  EurocImportOptions options;
  options.input = dir / "MH_01_easy";
  options.into = dir / "ds";
  options.agent = "mh01";
  const EurocImportSummary summary = ImportEuroc(options);
  EXPECT_EQ(summary.images, static_cast<size_t>(kImages));
  EXPECT_EQ(summary.poses, 60u);
  EXPECT_EQ(summary.images_outside_groundtruth, 2u);  // the first two images

  const Dataset dataset = ReadDataset(dir / "ds");
  ASSERT_EQ(dataset.air.count("mh01"), 1u);
  const AgentData& air = dataset.air.at("mh01");
  ExpectCalibrationOfFixture(air.calibration);
  ExpectTrajectoryOfFixture(air.groundtruth);
  ExpectTrajectoryOfFixture(air.odometry);
  ASSERT_EQ(air.images.size(), static_cast<size_t>(kImages));
  EXPECT_EQ(air.images[3].t_ns, kT0 + 3 * kImageStep);
  EXPECT_EQ(ReadText(air.images[3].path),
            ReadText(dir / ("MH_01_easy/mav0/cam0/data/" + std::to_string(kT0 + 3 * kImageStep) +
                            ".png")));
  EXPECT_FALSE(dataset.groundtruth.has_value());  // no --air-offset: not written
  EXPECT_FALSE(fs::exists(dir / "ds/air/.mh01.partial"));

  // A second agent with a T_wa_wg: groundtruth.yaml gets it; then a third
  // keeps the second's entry.
  options.agent = "mh01_b";
  options.air_offset = {1.0, -2.0, 0.5, 45.0};
  ImportEuroc(options);
  options.agent = "mh01_c";
  options.air_offset = {0, 0, 0, -90.0};
  ImportEuroc(options);
  const Dataset again = ReadDataset(dir / "ds");
  ASSERT_TRUE(again.groundtruth.has_value());
  EXPECT_EQ(again.groundtruth->T_wa_wg.at("mh01_b").matrix(),
            MakePose4Dof(1.0, -2.0, 0.5, M_PI / 4).matrix());
  EXPECT_EQ(again.groundtruth->T_wa_wg.at("mh01_c").matrix(),
            MakePose4Dof(0, 0, 0, -M_PI / 2).matrix());
  EXPECT_EQ(again.groundtruth->T_wa_wg.count("mh01"), 0u);
  EXPECT_EQ(again.air.size(), 3u);
}

TEST(EurocImport, RefusesAnExistingAgentAndLeavesTheDatasetAsItWas) {
  test::TempDir dir;
  WriteEurocFixture(dir / "seq");
  WriteGroundDataset(dir / "ds");
  EurocImportOptions options;
  options.input = dir / "seq";
  options.into = dir / "ds";
  options.agent = "uav";
  ImportEuroc(options);
  EXPECT_THROW(ImportEuroc(options), std::invalid_argument);

  // A broken image list fails before anything is written.
  WriteText(dir / "seq/mav0/cam0/data.csv", "#t,f\n5,missing.png\n");
  options.agent = "uav2";
  EXPECT_THROW(ImportEuroc(options), InputError);
  EXPECT_FALSE(fs::exists(dir / "ds/air/uav2"));
  EXPECT_EQ(ReadDataset(dir / "ds").air.size(), 1u);
}

TEST(EurocImport, NewDatasetWithTheGroundAgentOfAnother) {
  test::TempDir dir;
  WriteEurocFixture(dir / "MH_01_easy");
  WriteGroundDataset(dir / "ground_source");
  EurocImportOptions options;
  options.input = dir / "MH_01_easy/mav0";
  options.out_dir = dir / "new";
  options.ground_from = dir / "ground_source";
  options.agent = "mh01";
  options.drift_m_per_sqrt_s = 0.05;
  options.drift_yaw_deg_per_sqrt_s = 0.5;
  options.seed = 3;
  ImportEuroc(options);

  const Dataset source = ReadDataset(dir / "ground_source");
  const Dataset dataset = ReadDataset(dir / "new");
  EXPECT_EQ(dataset.name, "MH_01_easy");
  ASSERT_EQ(dataset.ground.images.size(), source.ground.images.size());
  ASSERT_EQ(dataset.ground.scans.size(), source.ground.scans.size());
  for (size_t i = 0; i < source.ground.scans.size(); ++i) {
    EXPECT_EQ(ReadText(dataset.ground.scans[i].path), ReadText(source.ground.scans[i].path));
    EXPECT_EQ(dataset.ground.odometry[i].T.matrix(), source.ground.odometry[i].T.matrix());
  }
  const AgentData& air = dataset.air.at("mh01");
  ExpectTrajectoryOfFixture(air.groundtruth);
  // Drifted odometry: starts on the truth, moves away, in x y z yaw only.
  ASSERT_EQ(air.odometry.size(), air.groundtruth.size());
  EXPECT_LT((air.odometry[0].T.matrix() - air.groundtruth[0].T.matrix()).cwiseAbs().maxCoeff(),
            1e-12);
  const Pose drift = air.odometry.back().T * air.groundtruth.back().T.inverse();
  EXPECT_GT(drift.translation().norm(), 1e-4);
  EXPECT_LT((drift.linear() - RotZ(ProjectedYaw(drift.linear()))).cwiseAbs().maxCoeff(), 1e-9);
  // Deterministic for a seed.
  const std::vector<StampedPose> again =
      AddRandomWalkDrift(air.groundtruth, 0.05, 0.5 * M_PI / 180.0, 3);
  EXPECT_LT((again.back().T.matrix() - air.odometry.back().T.matrix()).cwiseAbs().maxCoeff(),
            1e-12);
}

TEST(EurocImport, NeedsAGroundAgent) {
  EurocImportOptions options;
  options.input = "seq";
  options.out_dir = "new";  // without ground_from
  EXPECT_THROW(options.Check(), OptionError);
  options.out_dir.clear();  // neither into nor out_dir
  EXPECT_THROW(options.Check(), OptionError);
  options.into = "ds";
  EXPECT_NO_THROW(options.Check());
  options.ground_from = "other";
  EXPECT_THROW(options.Check(), OptionError);
}

#ifdef AG_IMPORT_EUROC_BINARY
TEST(EurocImportTool, RunsFromTheCommandLine) {
  test::TempDir dir;
  WriteEurocFixture(dir / "seq");
  WriteGroundDataset(dir / "ds");
  const std::string command = std::string(AG_IMPORT_EUROC_BINARY) + " " + (dir / "seq") +
                              " --out " + (dir / "new") + " --ground-from " + (dir / "ds") +
                              " --agent cli --air-offset=-3,2,1,10 > " + (dir / "log.txt") +
                              " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << ReadText(dir / "log.txt");
  const Dataset dataset = ReadDataset(dir / "new");
  ASSERT_TRUE(dataset.groundtruth.has_value());
  EXPECT_LT((dataset.groundtruth->T_wa_wg.at("cli").matrix() -
             MakePose4Dof(-3, 2, 1, 10 * M_PI / 180).matrix())
                .cwiseAbs()
                .maxCoeff(),
            1e-15);
  // No ground agent source: refused with a message saying why.
  const std::string bad = std::string(AG_IMPORT_EUROC_BINARY) + " " + (dir / "seq") + " --out " +
                          (dir / "new2") + " > " + (dir / "log2.txt") + " 2>&1";
  EXPECT_NE(std::system(bad.c_str()), 0);
  EXPECT_NE(ReadText(dir / "log2.txt").find("ground agent"), std::string::npos)
      << ReadText(dir / "log2.txt");
}
#endif

}  // namespace
}  // namespace ag
