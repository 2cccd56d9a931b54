// DatasetWriter -> ReadDataset round trip (every field compared) and the
// writer's own refusals.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

#include "common/dataset/dataset.h"
#include "common/dataset/yaml_io.h"
#include "tests/common/dataset/dataset_test_util.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;
using K = InputErrorKind;

Pose RandomPose(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Pose T = Pose::Identity();
  T.linear() = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 10.0;
  return T;
}

std::vector<StampedPose> RandomTrajectory(std::mt19937& rng, int64_t t0_ns, int n) {
  std::vector<StampedPose> poses;
  poses.reserve(n);
  for (int i = 0; i < n; ++i) poses.push_back({t0_ns + i * 10000003LL, RandomPose(rng)});
  return poses;
}

AgentCalibration RandomCalibration(std::mt19937& rng, const std::string& model, int n_distortion,
                                   bool lidar) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  AgentCalibration c;
  c.camera.camera.model = model;
  c.camera.camera.width = 40;
  c.camera.camera.height = 30;
  c.camera.camera.fx = 300.0 + u(rng);
  c.camera.camera.fy = 301.0 + u(rng);
  c.camera.camera.cx = 20.0 + u(rng);
  c.camera.camera.cy = 15.0 + u(rng);
  for (int i = 0; i < n_distortion; ++i) c.camera.camera.distortion.push_back(0.01 * u(rng));
  c.camera.T_body_camera = RandomPose(rng);
  c.camera.time_offset_s = 0.001 * u(rng);
  if (lidar) c.lidar = LidarCalibration{RandomPose(rng), 0.001 * u(rng)};
  return c;
}

// Bit-exact comparison of poses read from YAML (written exactly).
void ExpectSamePose(const Pose& a, const Pose& b, const std::string& what) {
  EXPECT_EQ(a.matrix(), b.matrix()) << what;
}

// Poses through TUM (quaternions, renormalised on reading).
void ExpectSameTrajectory(const std::vector<StampedPose>& a, const std::vector<StampedPose>& b,
                          const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].t_ns, b[i].t_ns) << what << " " << i;
    EXPECT_LT((a[i].T.matrix() - b[i].T.matrix()).cwiseAbs().maxCoeff(), 1e-14) << what << " " << i;
  }
}

void ExpectSameCalibration(const AgentCalibration& a, const AgentCalibration& b,
                           const std::string& what) {
  EXPECT_EQ(a.camera.camera.model, b.camera.camera.model) << what;
  EXPECT_EQ(a.camera.camera.width, b.camera.camera.width) << what;
  EXPECT_EQ(a.camera.camera.height, b.camera.camera.height) << what;
  EXPECT_EQ(a.camera.camera.fx, b.camera.camera.fx) << what;
  EXPECT_EQ(a.camera.camera.fy, b.camera.camera.fy) << what;
  EXPECT_EQ(a.camera.camera.cx, b.camera.camera.cx) << what;
  EXPECT_EQ(a.camera.camera.cy, b.camera.camera.cy) << what;
  EXPECT_EQ(a.camera.camera.distortion, b.camera.camera.distortion) << what;
  ExpectSamePose(a.camera.T_body_camera, b.camera.T_body_camera, what + " T_body_camera");
  EXPECT_EQ(a.camera.time_offset_s, b.camera.time_offset_s) << what;
  ASSERT_EQ(a.lidar.has_value(), b.lidar.has_value()) << what;
  if (a.lidar) {
    ExpectSamePose(a.lidar->T_body_lidar, b.lidar->T_body_lidar, what + " T_body_lidar");
    EXPECT_EQ(a.lidar->time_offset_s, b.lidar->time_offset_s) << what;
  }
}

void ExpectSameFrames(const std::vector<SensorFrame>& a, const std::vector<SensorFrame>& b,
                      const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].t_ns, b[i].t_ns) << what;
    EXPECT_EQ(a[i].filename, b[i].filename) << what;
    EXPECT_EQ(fs::path(a[i].path).lexically_normal(), fs::path(b[i].path).lexically_normal())
        << what;
  }
}

cv::Mat RandomImage(std::mt19937& rng, int type) {
  cv::Mat image(30, 40, type);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(256));
  (void)rng;
  return image;
}

TEST(DatasetWriterTest, WriteThenReadIsIdentical) {
  test::TempDir tmp;
  const std::string dir = tmp / "ds";
  std::mt19937 rng(42);
  const std::string description =
      "round trip: \"quotes\", colons: yes, #hash, tabs\there,\n"
      "second line, unicode \xc3\xa9\xe2\x86\x92";

  // Ground (radtan 5 + lidar), uav_a (equidistant), uav_b (radtan 4, no
  // groundtruth trajectory, no images).
  std::map<std::string, AgentCalibration> calibrations = {
      {"ground", RandomCalibration(rng, "pinhole", 5, true)},
      {"uav_a", RandomCalibration(rng, "equidistant", 4, false)},
      {"uav_b", RandomCalibration(rng, "pinhole", 4, false)}};
  std::map<std::string, std::vector<SensorFrame>> images;
  std::map<std::string, std::map<int64_t, cv::Mat>> pixels;
  std::map<std::string, std::vector<StampedPose>> odometry, groundtruth;
  std::vector<SensorFrame> scans;

  DatasetWriter writer(dir, "round trip", description);
  writer.BeginGround(calibrations["ground"]);
  writer.BeginAir("uav_a", calibrations["uav_a"]);
  writer.BeginAir("uav_b", calibrations["uav_b"]);
  for (const std::string agent : {"ground", "uav_a"}) {
    for (int i = 0; i < 5; ++i) {
      const int64_t t_ns = 1700000000000000000LL + i * 100000000LL + (agent == "ground" ? 7 : 0);
      const std::string path = writer.AddImage(agent, t_ns);
      const cv::Mat image = RandomImage(rng, i % 2 ? CV_8UC3 : CV_8UC1);
      ASSERT_TRUE(cv::imwrite(path, image));
      pixels[agent][t_ns] = image;
      images[agent].push_back({t_ns, std::to_string(t_ns) + ".png", path});
    }
  }
  for (int i = 0; i < 4; ++i) {
    const int64_t t_ns = 1700000000050000000LL + i * 100000000LL;
    const std::string path = writer.AddScan(t_ns);
    test::WriteText(path, "scan contents are not read by the dataset reader\n");
    scans.push_back({t_ns, std::to_string(t_ns) + ".pcd", path});
  }
  int64_t t0 = 1700000000000000000LL;
  for (const std::string agent : {"ground", "uav_a", "uav_b"}) {
    odometry[agent] = RandomTrajectory(rng, t0, 60);
    writer.SetOdometry(agent, odometry[agent]);
    t0 += 1234567;  // each agent has its own clock
  }
  groundtruth["ground"] = RandomTrajectory(rng, t0, 30);
  groundtruth["uav_a"] = RandomTrajectory(rng, t0 + 5, 30);
  writer.SetGroundTruthTrajectory("ground", groundtruth["ground"]);
  writer.SetGroundTruthTrajectory("uav_a", groundtruth["uav_a"]);

  DatasetGroundTruth gt;
  gt.T_wa_wg["uav_a"] = MakePose4Dof(1.5, -2.25, 0.125, 0.3);
  gt.T_wa_wg["uav_b"] = MakePose4Dof(-10.1, 3.3, 1.0 / 3.0, -2.9);
  gt.ground_true_camera = CameraCalibration{};
  gt.ground_true_camera->T_body_camera = RandomPose(rng);
  gt.ground_true_camera->time_offset_s = 0.0031;
  gt.ground_true_lidar = LidarCalibration{RandomPose(rng), 0.0};
  gt.air_true_camera["uav_a"].T_body_camera = RandomPose(rng);
  gt.air_true_camera["uav_a"].time_offset_s = -1e-3;
  gt.air_true_camera["uav_b"].T_body_camera = RandomPose(rng);
  writer.SetGroundTruth(gt);
  writer.Finish();

  const Dataset ds = ReadDataset(dir);
  EXPECT_EQ(ds.dir, dir);
  EXPECT_EQ(ds.format_version, 1);
  EXPECT_EQ(ds.name, "round trip");
  EXPECT_EQ(ds.description, description);

  auto check_agent = [&](const AgentData& agent, const std::string& name) {
    SCOPED_TRACE(name);
    EXPECT_EQ(agent.name, name);
    EXPECT_EQ(agent.dir, AgentDir(dir, name));
    ExpectSameCalibration(agent.calibration, calibrations[name], name);
    ExpectSameFrames(agent.images, images[name], name + " images");
    ExpectSameTrajectory(agent.odometry, odometry[name], name + " odometry");
    ExpectSameTrajectory(agent.groundtruth, groundtruth[name], name + " groundtruth");
    for (const SensorFrame& frame : agent.images) {
      const cv::Mat back = LoadImage(frame);
      const cv::Mat& expected = pixels[name][frame.t_ns];
      ASSERT_EQ(back.type(), expected.type());
      EXPECT_EQ(cv::norm(back, expected, cv::NORM_INF), 0.0) << frame.path;
    }
  };
  check_agent(ds.ground, "ground");
  ExpectSameFrames(ds.ground.scans, scans, "scans");
  ASSERT_EQ(ds.air.size(), 2u);
  check_agent(ds.air.at("uav_a"), "uav_a");
  check_agent(ds.air.at("uav_b"), "uav_b");
  EXPECT_TRUE(ds.air.at("uav_b").images.empty());
  EXPECT_FALSE(fs::exists(dir + "/air/uav_b/groundtruth.tum"));

  ASSERT_TRUE(ds.groundtruth.has_value());
  const DatasetGroundTruth& back = *ds.groundtruth;
  ASSERT_EQ(back.T_wa_wg.size(), 2u);
  ExpectSamePose(back.T_wa_wg.at("uav_a"), gt.T_wa_wg["uav_a"], "T_wa_wg uav_a");
  ExpectSamePose(back.T_wa_wg.at("uav_b"), gt.T_wa_wg["uav_b"], "T_wa_wg uav_b");
  ASSERT_TRUE(back.ground_true_camera.has_value());
  ExpectSamePose(back.ground_true_camera->T_body_camera, gt.ground_true_camera->T_body_camera,
                 "true ground T_body_camera");
  EXPECT_EQ(back.ground_true_camera->time_offset_s, 0.0031);
  ASSERT_TRUE(back.ground_true_lidar.has_value());
  ExpectSamePose(back.ground_true_lidar->T_body_lidar, gt.ground_true_lidar->T_body_lidar,
                 "true T_body_lidar");
  ASSERT_EQ(back.air_true_camera.size(), 2u);
  for (const auto& [agent, camera] : gt.air_true_camera) {
    ExpectSamePose(back.air_true_camera.at(agent).T_body_camera, camera.T_body_camera, agent);
    EXPECT_EQ(back.air_true_camera.at(agent).time_offset_s, camera.time_offset_s);
  }

  // The standalone readers agree with ReadDataset.
  ExpectSameCalibration(ReadCalibration(dir + "/air/uav_a/calibration.yaml", false),
                        calibrations["uav_a"], "ReadCalibration");
  EXPECT_EQ(ReadGroundTruth(dir + "/groundtruth.yaml").T_wa_wg.size(), 2u);
}

TEST(DatasetWriterTest, WrittenFilesFollowTheSpecText) {
  test::TempDir tmp;
  const std::string dir = tmp / "ds";
  DatasetWriter writer(dir, "spec", "");
  AgentCalibration calibration;
  calibration.camera.camera = {"pinhole", 640, 480, 500, 500, 320, 240, {}};
  calibration.camera.T_body_camera.translation() = Eigen::Vector3d(0.1, 0, 0);
  calibration.lidar = LidarCalibration{};
  writer.BeginGround(calibration);
  test::WriteText(writer.AddImage("ground", 1700000000000000000LL), "x");
  writer.Finish();
  EXPECT_EQ(test::ReadText(dir + "/ground/images.csv"),
            "#timestamp [ns],filename\n1700000000000000000,1700000000000000000.png\n");
  EXPECT_EQ(test::ReadText(dir + "/ground/scans.csv"), "#timestamp [ns],filename\n");
  const std::string yaml = test::ReadText(dir + "/ground/calibration.yaml");
  EXPECT_NE(yaml.find("  model: pinhole\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("  intrinsics: [500, 500, 320, 240]\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("  distortion: []\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("  T_body_camera: [[1, 0, 0, 0.1],\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("[0, 0, 0, 1]]\n"), std::string::npos) << yaml;
  EXPECT_EQ(test::ReadText(dir + "/dataset.yaml"),
            "format_version: 1\nname: \"spec\"\ndescription: \"\"\n");
  EXPECT_TRUE(fs::is_directory(dir + "/ground/scans"));
  EXPECT_TRUE(fs::is_regular_file(dir + "/ground/odometry.tum"));
  EXPECT_FALSE(fs::exists(dir + "/ground/groundtruth.tum"));
  EXPECT_FALSE(fs::exists(dir + "/groundtruth.yaml"));
  EXPECT_NO_THROW(ReadDataset(dir));
}

TEST(DatasetWriterTest, NumbersAreWrittenExactlyAndShort) {
  using internal::FormatDouble;
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(1.0), "1");
  EXPECT_EQ(FormatDouble(-0.0), "-0");
  EXPECT_EQ(FormatDouble(1.0 / 3.0), "0.3333333333333333");
  EXPECT_EQ(FormatDouble(500.0), "500");
  EXPECT_EQ(FormatDouble(1234567.0), "1234567");
  EXPECT_EQ(FormatDouble(1.76187114e-05), "1.76187114e-05");
  EXPECT_EQ(FormatDouble(0.1 + 0.2), "0.30000000000000004");
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<uint64_t> bits;
  for (int i = 0; i < 10000; ++i) {
    double value;
    const uint64_t b = bits(rng);
    std::memcpy(&value, &b, sizeof(value));
    if (!std::isfinite(value)) continue;
    const std::string text = FormatDouble(value);
    EXPECT_EQ(std::strtod(text.c_str(), nullptr), value) << text;
    EXPECT_LE(text.size(), 24u);
  }
}

AgentCalibration ValidCalibration(bool lidar) {
  AgentCalibration c;
  c.camera.camera = {"pinhole", 64, 48, 50, 50, 32, 24, {0.1, 0.01, 0, 0}};
  if (lidar) c.lidar = LidarCalibration{};
  return c;
}

TEST(DatasetWriterTest, RefusesANonEmptyFolder) {
  test::TempDir tmp;
  test::WriteText(tmp / "out/file.txt", "x");
  test::ExpectInputError([&] { DatasetWriter(tmp / "out", "n", "d"); }, K::kBadValue, tmp / "out",
                         0, "not empty");
  // An existing empty folder is fine.
  fs::create_directories(tmp / "empty");
  EXPECT_NO_THROW(DatasetWriter(tmp / "empty", "n", "d"));
}

TEST(DatasetWriterTest, RefusesBadAgentsAndCalibrations) {
  test::TempDir tmp;
  DatasetWriter writer(tmp / "ds", "n", "d");
  try {
    writer.BeginGround(ValidCalibration(false));
    ADD_FAILURE() << "ground without lidar accepted";
  } catch (const OptionError& e) {
    EXPECT_EQ(e.field(), "lidar");
  }
  AgentCalibration fisheye5 = ValidCalibration(false);
  fisheye5.camera.camera.model = "equidistant";
  fisheye5.camera.camera.distortion.resize(5);
  try {
    writer.BeginAir("uav", fisheye5);
    ADD_FAILURE() << "equidistant with 5 coefficients accepted";
  } catch (const OptionError& e) {
    EXPECT_EQ(e.field(), "distortion");
  }
  EXPECT_THROW(writer.BeginAir("UAV", ValidCalibration(false)), std::invalid_argument);
  EXPECT_THROW(writer.BeginAir("uav-1", ValidCalibration(false)), std::invalid_argument);
  EXPECT_THROW(writer.BeginAir("", ValidCalibration(false)), std::invalid_argument);
  EXPECT_THROW(writer.BeginAir("ground", ValidCalibration(false)), std::invalid_argument);
  writer.BeginAir("uav", ValidCalibration(false));
  EXPECT_THROW(writer.BeginAir("uav", ValidCalibration(false)), std::invalid_argument);
  EXPECT_THROW(writer.AddImage("uav2", 1), std::invalid_argument);
  EXPECT_THROW(writer.AddImage("uav", 1, ".bmp"), std::invalid_argument);
  EXPECT_THROW(writer.AddScan(1), std::invalid_argument);  // no ground yet
  EXPECT_THROW(writer.Finish(), std::logic_error);         // no ground agent
  writer.BeginGround(ValidCalibration(true));
  EXPECT_THROW(writer.BeginGround(ValidCalibration(true)), std::invalid_argument);
  DatasetGroundTruth gt;
  gt.T_wa_wg["uav9"] = Pose::Identity();
  writer.SetGroundTruth(gt);
  EXPECT_THROW(writer.Finish(), std::invalid_argument);
  writer.SetGroundTruth(DatasetGroundTruth{});
  writer.Finish();
  EXPECT_THROW(writer.Finish(), std::logic_error);
}

TEST(DatasetWriterTest, FinishRefusesUnsortedFramesAndWritesNothing) {
  test::TempDir tmp;
  const std::string dir = tmp / "ds";
  DatasetWriter writer(dir, "n", "d");
  writer.BeginGround(ValidCalibration(true));
  writer.BeginAir("uav", ValidCalibration(false));
  for (int64_t t : {10, 30, 20}) test::WriteText(writer.AddImage("uav", t), "x");
  test::ExpectInputError([&] { writer.Finish(); }, K::kUnsorted, dir + "/air/uav/images.csv", 4);
  EXPECT_FALSE(fs::exists(dir + "/ground/images.csv"));
  EXPECT_FALSE(fs::exists(dir + "/air/uav/images.csv"));
}

TEST(DatasetWriterTest, FinishRefusesUnsortedPoses) {
  test::TempDir tmp;
  const std::string dir = tmp / "ds";
  DatasetWriter writer(dir, "n", "d");
  writer.BeginGround(ValidCalibration(true));
  std::vector<StampedPose> poses(3);
  poses[0].t_ns = 1;
  poses[1].t_ns = 2;
  poses[2].t_ns = 2;
  writer.SetOdometry("ground", poses);
  test::ExpectInputError([&] { writer.Finish(); }, K::kUnsorted, dir + "/ground/odometry.tum", 4);
  poses[2].t_ns = 3;
  writer.SetOdometry("ground", poses);
  writer.SetGroundTruthTrajectory("ground", {poses[1], poses[0]});
  test::ExpectInputError([&] { writer.Finish(); }, K::kUnsorted, dir + "/ground/groundtruth.tum",
                         3);
}

TEST(DatasetWriterTest, FinishRefusesFramesNeverWritten) {
  test::TempDir tmp;
  const std::string dir = tmp / "ds";
  DatasetWriter writer(dir, "n", "d");
  writer.BeginGround(ValidCalibration(true));
  test::WriteText(writer.AddScan(5), "x");
  writer.AddScan(6);  // never written
  test::ExpectInputError([&] { writer.Finish(); }, K::kMissingFile, dir + "/ground/scans.csv", 3,
                         "6.pcd");
}

// A dataset of the size a 60 s scenario gives (100 Hz odometry, 10 Hz
// images and scans, three agents), read back. Prints the time; asserts only
// the content (no timing asserts in unit tests).
TEST(DatasetWriterTest, SixtySecondDatasetReads) {
  test::TempDir tmp;
  const std::string dir = tmp / "ds";
  std::mt19937 rng(1);
  DatasetWriter writer(dir, "60 s", "");
  writer.BeginGround(ValidCalibration(true));
  writer.BeginAir("uav1", ValidCalibration(false));
  writer.BeginAir("uav2", ValidCalibration(false));
  const int64_t t0 = 1700000000000000000LL;
  for (const std::string agent : {"ground", "uav1", "uav2"}) {
    std::vector<StampedPose> odometry;
    odometry.reserve(6000);
    for (int i = 0; i < 6000; ++i) odometry.push_back({t0 + i * 10000000LL, RandomPose(rng)});
    writer.SetOdometry(agent, odometry);
    writer.SetGroundTruthTrajectory(agent, odometry);
    for (int i = 0; i < 600; ++i) test::WriteText(writer.AddImage(agent, t0 + i * 100000000LL), "");
  }
  for (int i = 0; i < 600; ++i) test::WriteText(writer.AddScan(t0 + i * 100000000LL + 1), "");
  writer.Finish();
  const auto start = std::chrono::steady_clock::now();
  const Dataset ds = ReadDataset(dir);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "ReadDataset: 3 agents x (6000 odometry + 6000 groundtruth + 600 images) + 600 "
      "scans in %.3f s\n",
      seconds);
  EXPECT_EQ(ds.ground.odometry.size(), 6000u);
  EXPECT_EQ(ds.air.at("uav2").groundtruth.size(), 6000u);
  EXPECT_EQ(ds.ground.scans.size(), 600u);
  EXPECT_EQ(ds.air.at("uav1").images.size(), 600u);
}

}  // namespace
}  // namespace ag
