// The dataset checker: a valid dataset passes with the right summary, each
// kind of breakage is reported with the file (and line) it is in, warnings
// for legal but suspect timing, --quick reads a sample. The tool binary and
// its wrapper script are run too.

#include "tools/dataset_checker/dataset_check.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/core/error.h"
#include "common/dataset/dataset.h"
#include "common/pcd/pcd_io.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

constexpr int64_t kT0 = 1700000000000000000;

AgentCalibration Calibration(bool lidar) {
  AgentCalibration c;
  c.camera.camera = {"pinhole", 64, 48, 50, 50, 32, 24, {}};
  if (lidar) c.lidar = LidarCalibration{};
  return c;
}

/// A valid dataset: ground (20 images at 10 Hz, 20 scans, odometry at 20 Hz
/// covering them) and air agent "uav1" (20 images, odometry, ground truth),
/// groundtruth.yaml with uav1's T_wa_wg. `odometry_step_ns` slows the
/// ground odometry down; `late_odometry_ns` starts it after the first frames.
void WriteDataset(const std::string& dir, int64_t odometry_step_ns = 50000000,
                  int64_t late_odometry_ns = 0) {
  DatasetWriter writer(dir, "check fixture", "written by dataset_check_test");
  writer.BeginGround(Calibration(true));
  writer.BeginAir("uav1", Calibration(false));
  for (int i = 0; i < 20; ++i) {
    const int64_t t = kT0 + i * 100000000LL;
    cv::imwrite(writer.AddImage("ground", t), cv::Mat(48, 64, CV_8UC1, cv::Scalar(i)));
    cv::imwrite(writer.AddImage("uav1", t + 1000), cv::Mat(48, 64, CV_8UC3, cv::Scalar(i)));
    PointCloud cloud;
    for (int k = 0; k < 10; ++k) cloud.points.emplace_back(k, i, 1.0f);
    WriteScan(writer.AddScan(t + 2000), cloud);
  }
  std::vector<StampedPose> ground, air;
  for (int64_t t = kT0 + late_odometry_ns; t <= kT0 + 2000000000LL; t += odometry_step_ns) {
    ground.push_back({t, MakePose4Dof(1e-9 * double(t - kT0), 0, 0, 0)});
  }
  for (int64_t t = kT0; t <= kT0 + 2000000000LL; t += 10000000) {
    air.push_back({t, MakePose4Dof(0, 1e-9 * double(t - kT0), 5, 0)});
  }
  writer.SetOdometry("ground", ground);
  writer.SetOdometry("uav1", air);
  writer.SetGroundTruthTrajectory("uav1", air);
  DatasetGroundTruth truth;
  truth.T_wa_wg["uav1"] = MakePose4Dof(1, 2, 3, 0.5);
  writer.SetGroundTruth(truth);
  writer.Finish();
}

/// Checks CheckDataset throws InputError naming `file` (and its line).
void ExpectInvalid(const std::string& dir, const std::string& file, int64_t line,
                   const std::string& fragment) {
  try {
    CheckDataset(dir);
    ADD_FAILURE() << "no InputError for " << file;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file) << e.what();
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(DatasetCheck, ValidDatasetSummary) {
  test::TempDir dir;
  WriteDataset(dir / "ds");
  const DatasetCheckReport report = CheckDataset(dir / "ds");
  ASSERT_EQ(report.agents.size(), 2u);
  const AgentCheck& ground = report.agents[0];
  const AgentCheck& air = report.agents[1];
  EXPECT_EQ(ground.name, "ground");
  EXPECT_EQ(air.name, "uav1");
  EXPECT_EQ(ground.images.count, 20u);
  EXPECT_EQ(ground.images_read, 20u);
  EXPECT_EQ(ground.scans_read, 20u);
  EXPECT_EQ(ground.scan_points_read, 200u);
  EXPECT_NEAR(ground.images.rate_hz, 10.0, 1e-9);
  EXPECT_NEAR(ground.odometry.rate_hz, 20.0, 1e-9);
  EXPECT_NEAR(air.odometry.rate_hz, 100.0, 1e-9);
  EXPECT_NEAR(ground.images.DurationSeconds(), 1.9, 1e-9);
  EXPECT_EQ(ground.width, 64);
  EXPECT_EQ(ground.height, 48);
  EXPECT_EQ(ground.groundtruth.count, 0u);
  EXPECT_EQ(air.groundtruth.count, air.odometry.count);
  EXPECT_EQ(ground.images_outside_odometry, 0u);
  EXPECT_TRUE(report.has_groundtruth_yaml);
  EXPECT_EQ(report.T_wa_wg_agents, std::vector<std::string>{"uav1"});
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front();
  EXPECT_GT(report.bytes, ground.bytes + air.bytes);  // + dataset.yaml, groundtruth.yaml
  const std::string text = FormatReport(report);
  EXPECT_NE(text.find("ground "), std::string::npos) << text;
  EXPECT_NE(text.find("uav1 "), std::string::npos) << text;
  EXPECT_NE(text.find("64x48"), std::string::npos) << text;
  EXPECT_NE(text.find("T_wa_wg for uav1"), std::string::npos) << text;
  EXPECT_NE(text.find("no warnings"), std::string::npos) << text;
}

TEST(DatasetCheck, QuickReadsASample) {
  test::TempDir dir;
  WriteDataset(dir / "ds");
  DatasetCheckOptions options;
  options.quick = true;
  options.quick_samples = 4;
  const DatasetCheckReport report = CheckDataset(dir / "ds", options);
  EXPECT_EQ(report.agents[0].images_read, 4u);
  EXPECT_EQ(report.agents[0].scans_read, 4u);
  EXPECT_EQ(report.agents[1].images_read, 4u);
  // A broken image outside the sample is not seen by --quick, but is by the
  // full check.
  const Dataset dataset = ReadDataset(dir / "ds");
  const std::string unsampled = dataset.ground.images[2].path;
  std::ofstream(unsampled, std::ios::binary) << "not a png";
  EXPECT_NO_THROW(CheckDataset(dir / "ds", options));
  ExpectInvalid(dir / "ds", unsampled, 0, "cannot read the image");
}

TEST(DatasetCheck, ReportsEachBreakageWithItsFile) {
  test::TempDir dir;
  const std::string ds = dir / "ds";
  WriteDataset(ds);
  const Dataset dataset = ReadDataset(ds);

  // An image of the wrong size.
  const std::string image = dataset.air.at("uav1").images[5].path;
  cv::imwrite(image, cv::Mat(48, 63, CV_8UC3));
  ExpectInvalid(ds, image, 0, "63x48");
  cv::imwrite(image, cv::Mat(48, 64, CV_8UC3));
  EXPECT_NO_THROW(CheckDataset(ds));

  // A scan PCL cannot read.
  const std::string scan = dataset.ground.scans[7].path;
  const std::string scan_bytes = ReadText(scan);
  std::ofstream(scan, std::ios::binary) << "# .PCD v0.7\nFIELDS x y\n";
  try {
    CheckDataset(ds);
    ADD_FAILURE() << "broken scan not reported";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), scan) << e.what();
  }
  std::ofstream(scan, std::ios::binary) << scan_bytes;
  EXPECT_NO_THROW(CheckDataset(ds));

  // An index file the reader refuses (line 3 of odometry.tum).
  const std::string tum = ds + "/ground/odometry.tum";
  const std::string tum_text = ReadText(tum);
  std::string broken = tum_text;
  const size_t line3 = broken.find('\n', broken.find('\n') + 1) + 1;
  broken.insert(line3, "1700000000.5 0 0 nan 0 0 0 1\n");
  std::ofstream(tum, std::ios::binary) << broken;
  ExpectInvalid(ds, tum, 3, "non-finite");
}

TEST(DatasetCheck, WarnsAboutSuspectTiming) {
  test::TempDir dir;
  // Ground odometry at 5 Hz from 0.45 s to 1.85 s: frames at 0.0 .. 0.4 s
  // and 1.9 s have no pose around them.
  WriteDataset(dir / "ds", 200000000, 450000000);
  const DatasetCheckReport report = CheckDataset(dir / "ds");
  EXPECT_EQ(report.agents[0].images_outside_odometry, 6u);
  EXPECT_EQ(report.agents[0].scans_outside_odometry, 6u);
  std::string all;
  for (const std::string& w : report.warnings) all += w + "\n";
  EXPECT_NE(all.find("ground: odometry rate 5.00 Hz is below 9.0 Hz"), std::string::npos) << all;
  EXPECT_NE(all.find("ground: 6 of 20 images are timed outside the odometry"), std::string::npos)
      << all;
  EXPECT_EQ(all.find("uav1"), std::string::npos) << all;
}

#ifdef AG_DATASET_CHECK_BINARY
int RunShell(const std::string& command, const std::string& log, std::string* output) {
  const int status = std::system((command + " > \"" + log + "\" 2>&1").c_str());
  *output = ReadText(log);
  return status;
}

TEST(DatasetCheckTool, ExitStatusAndMessages) {
  test::TempDir dir;
  WriteDataset(dir / "ds");
  std::string out;
  EXPECT_EQ(RunShell(std::string(AG_DATASET_CHECK_BINARY) + " " + (dir / "ds"), dir / "log", &out),
            0)
      << out;
  EXPECT_NE(out.find("ground "), std::string::npos) << out;
  EXPECT_NE(out.find("uav1 "), std::string::npos) << out;
  EXPECT_NE(out.find("RESULT: valid"), std::string::npos) << out;

  // Broken: a row of images.csv names a file that is not there.
  const std::string csv = dir / "ds/air/uav1/images.csv";
  std::ofstream(csv, std::ios::app) << "1800000000000000000,absent.png\n";
  EXPECT_NE(RunShell(std::string(AG_DATASET_CHECK_BINARY) + " " + (dir / "ds"), dir / "log", &out),
            0)
      << out;
  EXPECT_NE(out.find("INVALID: " + csv + ":22:"), std::string::npos) << out;
  EXPECT_NE(out.find("absent.png"), std::string::npos) << out;
}

TEST(DatasetCheckTool, WrapperScript) {
  test::TempDir dir;
  WriteDataset(dir / "ds");
  std::string out;
  // The script finds the binary in AG_BUILD_DIR ...
  const std::string build_dir = test::BuildDir();
  {
    EXPECT_EQ(RunShell(std::string("AG_BUILD_DIR=\"") + build_dir + "\" " +
                           AG_CHECK_DATASET_SCRIPT + " --quick " + (dir / "ds"),
                       dir / "log", &out),
              0)
        << out;
    EXPECT_NE(out.find("RESULT: valid"), std::string::npos) << out;
  }
  // ... and says clearly when it is not built.
  EXPECT_NE(RunShell(std::string("AG_BUILD_DIR=\"") + dir.path() + "\" " + AG_CHECK_DATASET_SCRIPT +
                         " " + (dir / "ds"),
                     dir / "log", &out),
            0);
  EXPECT_NE(out.find("is not built"), std::string::npos) << out;
}
#endif

}  // namespace
}  // namespace ag
