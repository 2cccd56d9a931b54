// Runs tools/sim/simulate (the executable) on the small preset and checks the
// dataset it writes: format, LiDAR / depth consistency under the true
// calibration, determinism, and the preview image.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "common/camera/camera.h"
#include "common/dataset/dataset.h"
#include "common/geometry/pose.h"
#include "common/pcd/pcd_io.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

std::string Tool() { return AG_SIM_TOOL; }
std::string SmallScenario() { return test::SourceDir() + "/config/scenarios/small.yaml"; }

int RunTool(const std::string& args) {
  const std::string command =
      Tool() + " --scenario " + SmallScenario() + " --log-level warn " + args;
  return std::system(command.c_str());
}

/// Every file below `dir`, relative, sorted.
std::vector<std::string> Files(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (entry.is_regular_file()) out.push_back(fs::relative(entry.path(), dir).string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::string Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

class SimulateTool : public ::testing::Test {
 protected:
  test::TempDir temp_;
};

/// Median signed and absolute depth residual of the LiDAR points of scans
/// projected into the nearest images, with the given calibration.
struct Residuals {
  double median_signed = 0.0;
  double median_abs = 0.0;
  size_t count = 0;
};

Residuals LidarVersusDepth(const Dataset& ds, const std::string& dir,
                           const CameraCalibration& camera_cal, const LidarCalibration& lidar_cal) {
  const Camera camera(ds.ground.calibration.camera.camera);
  const auto& gt = ds.ground.groundtruth;
  std::vector<double> residuals;
  for (size_t j = 3; j + 3 < ds.ground.scans.size(); j += 4) {
    const SensorFrame& scan = ds.ground.scans[j];
    // The image closest in time: the two views then share most surfaces.
    const auto& images = ds.ground.images;
    const auto nearest =
        std::min_element(images.begin(), images.end(), [&](const auto& a, const auto& b) {
          return std::llabs(a.t_ns - scan.t_ns) < std::llabs(b.t_ns - scan.t_ns);
        });
    // Sensor clocks to body time: t_body = t_sensor + time_offset.
    const auto T_lidar =
        InterpolateInBuffer(gt, scan.t_ns + std::llround(lidar_cal.time_offset_s * 1e9));
    const auto T_cam =
        InterpolateInBuffer(gt, nearest->t_ns + std::llround(camera_cal.time_offset_s * 1e9));
    if (!T_lidar.ok() || !T_cam.ok()) continue;
    const Pose T_camera_lidar =
        (T_cam.T * camera_cal.T_body_camera).inverse() * T_lidar.T * lidar_cal.T_body_lidar;
    const cv::Mat depth = cv::imread(
        dir + "/ground/depth/" + std::to_string(nearest->t_ns) + ".tiff", cv::IMREAD_UNCHANGED);
    const PointCloud cloud = ReadScan(scan.path);
    for (const Eigen::Vector3f& p : cloud.points) {
      const Eigen::Vector3d p_c = T_camera_lidar * p.cast<double>();
      Eigen::Vector2d uv;
      if (p_c.z() < 0.5 || !camera.Project(p_c, &uv) || !camera.InImage(uv, 1.0)) continue;
      const int u0 = static_cast<int>(std::floor(uv.x())),
                v0 = static_cast<int>(std::floor(uv.y()));
      double z[4];
      bool ok = true;
      for (int k = 0; k < 4; ++k) {
        z[k] = depth.at<float>(v0 + (k >> 1), u0 + (k & 1));
        ok = ok && z[k] > 0.0;
      }
      if (!ok) continue;
      const auto [lo, hi] = std::minmax({z[0], z[1], z[2], z[3]});
      if (hi > 1.03 * lo) continue;  // a depth edge: the interpolation is meaningless there
      const double fu = uv.x() - u0, fv = uv.y() - v0;
      // Inverse depth is affine across a plane: interpolate that.
      const double inv =
          (1 - fv) * ((1 - fu) / z[0] + fu / z[1]) + fv * ((1 - fu) / z[2] + fu / z[3]);
      residuals.push_back(p_c.z() - 1.0 / inv);
    }
  }
  Residuals r;
  r.count = residuals.size();
  if (residuals.empty()) return r;
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  r.median_signed = median(residuals);
  for (double& x : residuals) x = std::fabs(x);
  r.median_abs = median(residuals);
  return r;
}

// One run of the tool on the small preset (the slow part), checked several ways.
TEST_F(SimulateTool, SmallPresetReadsBackAndLidarAgreesWithDepth) {
  const std::string dataset_dir = temp_ / "small";
  ASSERT_EQ(RunTool("--seed 3 --out " + dataset_dir), 0) << "simulate failed: " << Tool();

  const Dataset ds = ReadDataset(dataset_dir);
  EXPECT_EQ(ds.name, "small");
  EXPECT_GE(ds.ground.images.size(), 15u);
  EXPECT_GE(ds.ground.scans.size(), 15u);
  ASSERT_EQ(ds.air.count("uav1"), 1u);
  EXPECT_GE(ds.air.at("uav1").images.size(), 15u);
  EXPECT_GE(ds.ground.odometry.size(), 150u);  // 100 Hz over 2 s
  EXPECT_EQ(ds.ground.groundtruth.size(), ds.ground.odometry.size());
  ASSERT_TRUE(ds.groundtruth.has_value());
  const Pose& T_wa_wg = ds.groundtruth->T_wa_wg.at("uav1");
  EXPECT_NEAR(T_wa_wg.linear()(2, 2), 1.0, 1e-12);  // 4 DoF
  ASSERT_TRUE(ds.groundtruth->ground_true_camera.has_value());
  // Ground-truth depth beside every image (small preset: on).
  for (const auto& frame : ds.ground.images) {
    const cv::Mat depth =
        cv::imread(dataset_dir + "/ground/depth/" + std::to_string(frame.t_ns) + ".tiff",
                   cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(depth.empty()) << frame.t_ns;
    EXPECT_EQ(depth.type(), CV_32FC1);
  }
  const cv::Mat image = cv::imread(ds.ground.images.front().path, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);

  // LiDAR points of scans, moved with the TRUE calibration and poses into the
  // image closest in time, land on the ground-truth depth.

  ASSERT_TRUE(ds.groundtruth && ds.groundtruth->ground_true_camera &&
              ds.groundtruth->ground_true_lidar);
  const Residuals truth = LidarVersusDepth(ds, dataset_dir, *ds.groundtruth->ground_true_camera,
                                           *ds.groundtruth->ground_true_lidar);
  ASSERT_GT(truth.count, 5000u);
  // Unbiased to well under a centimetre; the spread is the 2 cm range noise.
  EXPECT_LT(std::fabs(truth.median_signed), 0.01);
  EXPECT_LT(truth.median_abs, 0.02);
  // The nominal calibration (what calibration.yaml says) is measurably off:
  // that is the error the first optimisation stage must absorb.
  const Residuals nominal =
      LidarVersusDepth(ds, dataset_dir, ds.ground.calibration.camera, *ds.ground.calibration.lidar);
  EXPECT_GT(nominal.median_abs, truth.median_abs);
  std::printf(
      "LiDAR vs depth over %zu points: true calibration median %.2f mm (|.| %.2f mm), nominal |.| "
      "%.2f mm\n",
      truth.count, 1e3 * truth.median_signed, 1e3 * truth.median_abs, 1e3 * nominal.median_abs);
}

TEST_F(SimulateTool, SameSeedGivesByteIdenticalDatasetsOtherSeedsDiffer) {
  const std::string a = temp_ / "a", b = temp_ / "b", c = temp_ / "c";
  ASSERT_EQ(RunTool("--seed 5 --duration 0.5 --threads 2 --out " + a), 0);
  ASSERT_EQ(RunTool("--seed 5 --duration 0.5 --threads 1 --out " + b), 0);
  ASSERT_EQ(RunTool("--seed 6 --duration 0.5 --out " + c), 0);
  const std::vector<std::string> files = Files(a);
  ASSERT_GT(files.size(), 20u);
  ASSERT_EQ(files, Files(b));
  for (const std::string& f : files) EXPECT_TRUE(Bytes(a + "/" + f) == Bytes(b + "/" + f)) << f;
  // Another seed: another world, calibration and noise.
  EXPECT_NE(Bytes(a + "/groundtruth.yaml"), Bytes(c + "/groundtruth.yaml"));
  const Dataset da = ReadDataset(a), dc = ReadDataset(c);
  EXPECT_NE(Bytes(da.ground.images.front().path), Bytes(dc.ground.images.front().path));
}

TEST_F(SimulateTool, PreviewShowsAnAirAndAGroundViewSideBySide) {
  const std::string png = temp_ / "preview.png";
  ASSERT_EQ(RunTool("--seed 3 --preview " + png), 0);
  const cv::Mat image = cv::imread(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.rows, 480);
  EXPECT_EQ(image.cols, 640 + 8 + 640);
}

TEST_F(SimulateTool, RejectsABadScenario) {
  const std::string bad = temp_ / "bad.yaml";
  std::ofstream(bad) << "name: bad\nworld:\n  size_x_m: 60\n  colour: red\nair:\n  uav1: {}\n";
  const std::string command =
      Tool() + " --scenario " + bad + " --out " + (temp_ / "bad") + " 2>/dev/null";
  EXPECT_NE(std::system(command.c_str()), 0);
}

}  // namespace
}  // namespace ag
