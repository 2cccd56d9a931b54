// tools/import_kitti on the real KITTI drive of ../shared (5 frames of
// 2011_09_26_drive_0001): what is imported, exact timestamps, the dataset
// reads back, and the one check that catches every convention error at once
// (frame direction, baseline sign, rectification, LiDAR frame): the imported
// LiDAR projected into the imported camera with the imported calibration
// puts its depth edges on image edges, clearly better than a perturbed
// extrinsic does.

#include "tools/importers/kitti_import.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "common/dataset/dataset.h"
#include "common/geometry/tum_io.h"
#include "common/pcd/pcd_io.h"
#include "tests/support/test_support.h"
#include "tools/importers/kitti_raw.h"

namespace ag {
namespace {

constexpr const char* kDrive =
    "data/kitti_raw_2011_09_26_drive_0001_mini/2011_09_26/2011_09_26_drive_0001_sync";

// First lines of image_02/timestamps.txt, velodyne_points/timestamps.txt and
// oxts/timestamps.txt of the drive, converted by hand (UTC).
// 2011-09-26 00:00:00 UTC = 15243 days after 1970-01-01 = 1316995200 s.
constexpr int64_t kDayStartS = 1316995200;
constexpr int64_t kFirstImageNs = (kDayStartS + 13 * 3600 + 2 * 60 + 25) * 1000000000LL + 961661696;
constexpr int64_t kFirstScanNs = (kDayStartS + 13 * 3600 + 2 * 60 + 25) * 1000000000LL + 951199337;
constexpr int64_t kFirstOxtsNs = (kDayStartS + 13 * 3600 + 2 * 60 + 25) * 1000000000LL + 964389445;
constexpr int64_t kLastImageNs = (kDayStartS + 13 * 3600 + 2 * 60 + 26) * 1000000000LL + 374087680;

double MaxAbsDiff(const Pose& a, const Pose& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

/// How well LiDAR depth edges meet image edges for one extrinsic.
struct Alignment {
  size_t edge_points = 0;    ///< projected depth-edge points
  double mean_gradient = 0;  ///< mean Sobel magnitude at their pixels
  double on_image_edge = 0;  ///< fraction on an image edge (see AccumulateAlignment)
};

// A depth edge: neighbours in a Velodyne ring (the .bin, and so the PCD,
// stores each ring in azimuth order) less than kRingStepRad apart whose
// ranges differ by more than kJumpM and kJumpFraction; the nearer point lies
// on an occluding contour, where the image has an edge too.
constexpr double kRingStepRad = 0.4 * M_PI / 180.0;
constexpr float kJumpM = 1.0f;
constexpr float kJumpFraction = 0.15f;
constexpr double kMinDepthM = 2.0;
// A point is on an image edge when the largest gradient of its row within
// +-kEdgeSearchPx lies within +-kEdgeTolerancePx of it. Random placement
// scores about 1/8; the contours are mostly vertical (ring neighbours are
// horizontal), so the row is the direction to search.
constexpr int kEdgeSearchPx = 12;
constexpr int kEdgeTolerancePx = 1;

/// Smoothed Sobel gradient magnitude of the grey image.
cv::Mat GradientMagnitude(const cv::Mat& image) {
  cv::Mat grey, blurred, gx, gy, magnitude;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  cv::GaussianBlur(grey, blurred, cv::Size(5, 5), 1.0);
  cv::Sobel(blurred, gx, CV_32F, 1, 0, 3);
  cv::Sobel(blurred, gy, CV_32F, 0, 1, 3);
  cv::magnitude(gx, gy, magnitude);
  return magnitude;
}

std::vector<size_t> DepthEdgePoints(const PointCloud& cloud) {
  std::vector<size_t> edges;
  const std::vector<Eigen::Vector3f>& p = cloud.points;
  for (size_t i = 0; i + 1 < p.size(); ++i) {
    const double step =
        std::abs(std::atan2(p[i].y(), p[i].x()) - std::atan2(p[i + 1].y(), p[i + 1].x()));
    if (step > kRingStepRad) continue;  // ring change or wrap-around
    const float ra = p[i].norm(), rb = p[i + 1].norm();
    if (std::abs(ra - rb) > std::max(kJumpM, kJumpFraction * std::min(ra, rb))) {
      edges.push_back(ra < rb ? i : i + 1);
    }
  }
  return edges;
}

void AccumulateAlignment(const cv::Mat& gradient, const PointCloud& cloud,
                         const Pose& T_camera_lidar, const CameraParams& camera,
                         Alignment* alignment) {
  for (size_t i : DepthEdgePoints(cloud)) {
    const Eigen::Vector3d p_c = T_camera_lidar * cloud.points[i].cast<double>();
    if (p_c.z() < kMinDepthM) continue;
    const int u = static_cast<int>(std::lround(camera.fx * p_c.x() / p_c.z() + camera.cx));
    const int v = static_cast<int>(std::lround(camera.fy * p_c.y() / p_c.z() + camera.cy));
    if (u < kEdgeSearchPx || v < 0 || u >= camera.width - kEdgeSearchPx || v >= camera.height) {
      continue;
    }
    float near = 0, far = 0;
    for (int du = -kEdgeSearchPx; du <= kEdgeSearchPx; ++du) {
      float& best = std::abs(du) <= kEdgeTolerancePx ? near : far;
      best = std::max(best, gradient.at<float>(v, u + du));
    }
    alignment->mean_gradient += gradient.at<float>(v, u);
    alignment->on_image_edge += near >= far ? 1.0 : 0.0;
    ++alignment->edge_points;
  }
}

Alignment MeasureAlignment(const Dataset& dataset, const Pose& T_camera_lidar) {
  Alignment alignment;
  const AgentData& ground = dataset.ground;
  for (size_t i = 0; i < ground.images.size(); ++i) {
    AccumulateAlignment(GradientMagnitude(LoadImage(ground.images[i], cv::IMREAD_COLOR)),
                        ReadScan(ground.scans[i].path), T_camera_lidar,
                        ground.calibration.camera.camera, &alignment);
  }
  if (alignment.edge_points > 0) {
    alignment.mean_gradient /= double(alignment.edge_points);
    alignment.on_image_edge /= double(alignment.edge_points);
  }
  return alignment;
}

// A rotation about the camera's y axis (image-horizontal shift, "yaw" of a
// forward-looking camera) or x axis (pitch), applied in the camera frame.
Pose CameraRotation(const Eigen::Vector3d& axis, double deg) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(deg * M_PI / 180.0, axis).toRotationMatrix();
  return T;
}

Pose CameraShift(const Eigen::Vector3d& t) {
  Pose T = Pose::Identity();
  T.translation() = t;
  return T;
}

class KittiImportTest : public ::testing::Test {
 protected:
  // Imports once for all tests (the import takes well under a second, but
  // the projection test reads every image and scan).
  static void Import(const std::string& drive, KittiImportOptions options) {
    if (out_) return;
    out_ = new test::TempDir;
    options.input = drive;
    options.out_dir = *out_ / "kitti";
    summary_ = new KittiImportSummary(ImportKittiRaw(options));
  }
  static void TearDownTestSuite() {
    delete out_;
    delete summary_;
    out_ = nullptr;
    summary_ = nullptr;
  }
  static KittiImportOptions PseudoAirOptions() {
    KittiImportOptions options;
    options.pseudo_air = "kitti_air";
    options.air_camera = "image_03";
    options.air_offset = {-5.0, 2.5, 1.25, 30.0};
    return options;
  }
  static test::TempDir* out_;
  static KittiImportSummary* summary_;
};
test::TempDir* KittiImportTest::out_ = nullptr;
KittiImportSummary* KittiImportTest::summary_ = nullptr;

TEST_F(KittiImportTest, ImportsTheFiveFramesThatExistNotThe108Listed) {
  AG_REQUIRE_SHARED(drive, kDrive);
  Import(drive, PseudoAirOptions());
  ASSERT_EQ(summary_->sensors.size(), 4u);  // image_02, velodyne_points, oxts, image_03
  for (const KittiSensorCount& s : summary_->sensors) {
    EXPECT_EQ(s.listed, 108u) << s.sensor;
    EXPECT_EQ(s.imported, 5u) << s.sensor;
    EXPECT_EQ(s.Skipped(), 103u) << s.sensor;
  }
  const Dataset dataset = ReadDataset(*out_ / "kitti");
  EXPECT_EQ(dataset.ground.images.size(), 5u);
  EXPECT_EQ(dataset.ground.scans.size(), 5u);
  EXPECT_EQ(dataset.ground.odometry.size(), 5u);
  ASSERT_EQ(dataset.air.size(), 1u);
  EXPECT_EQ(dataset.air.at("kitti_air").images.size(), 5u);
  // The first image and scan (and image_03's) precede the first OXTS packet.
  EXPECT_EQ(summary_->frames_outside_odometry, 3u);
}

TEST_F(KittiImportTest, TimestampsAreExact) {
  AG_REQUIRE_SHARED(drive, kDrive);
  Import(drive, PseudoAirOptions());
  const Dataset dataset = ReadDataset(*out_ / "kitti");
  EXPECT_EQ(dataset.ground.images.front().t_ns, kFirstImageNs);
  EXPECT_EQ(dataset.ground.images.back().t_ns, kLastImageNs);
  EXPECT_EQ(dataset.ground.scans.front().t_ns, kFirstScanNs);
  EXPECT_EQ(dataset.ground.odometry.front().t_ns, kFirstOxtsNs);
  EXPECT_EQ(dataset.ground.groundtruth.front().t_ns, kFirstOxtsNs);
  // Every row equals its line of timestamps.txt parsed independently.
  const std::vector<int64_t> listed = ReadKittiTimestamps(drive + "/image_02/timestamps.txt");
  for (size_t i = 0; i < dataset.ground.images.size(); ++i) {
    EXPECT_EQ(dataset.ground.images[i].t_ns, listed[i]) << i;
  }
}

TEST_F(KittiImportTest, PosesStartAtTheOriginAndGroundTruthEqualsOdometry) {
  AG_REQUIRE_SHARED(drive, kDrive);
  Import(drive, PseudoAirOptions());
  const Dataset dataset = ReadDataset(*out_ / "kitti");
  const std::vector<StampedPose>& odometry = dataset.ground.odometry;
  ASSERT_EQ(dataset.ground.groundtruth.size(), odometry.size());
  for (size_t i = 0; i < odometry.size(); ++i) {
    EXPECT_EQ(dataset.ground.groundtruth[i].t_ns, odometry[i].t_ns);
    EXPECT_EQ(dataset.ground.groundtruth[i].T.matrix(), odometry[i].T.matrix()) << i;
  }
  // Gravity-aligned world at the first OXTS pose: zero position and
  // heading; the first pose keeps the OXTS roll and pitch (0.0358, 0.0090).
  const Pose& first = odometry.front().T;
  EXPECT_EQ(first.translation(), Eigen::Vector3d::Zero());
  EXPECT_NEAR(YawOf(first.linear()), 0.0, 1e-12);
  const OxtsPacket packet = ReadOxtsPacket(drive + "/oxts/data/0000000000.txt");
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(packet.pitch, Eigen::Vector3d::UnitY()) *
                                Eigen::AngleAxisd(packet.roll, Eigen::Vector3d::UnitX()))
                                   .toRotationMatrix();
  EXPECT_LT((first.linear() - tilt).cwiseAbs().maxCoeff(), 1e-12);
  // The car drives forward (+x of the IMU) at about 10 m/s in 0.42 s.
  const Eigen::Vector3d last = odometry.back().T.translation();
  EXPECT_GT(last.x(), 4.0);
  EXPECT_LT(last.x(), 6.0);
  EXPECT_LT(std::abs(last.y()), 0.2);
}

TEST(KittiImport, DevkitWorldStartsExactlyAtIdentity) {
  AG_REQUIRE_SHARED(drive, kDrive);
  test::TempDir out;
  KittiImportOptions options;
  options.input = drive;
  options.out_dir = out / "kitti";
  options.world = "first-pose";
  ImportKittiRaw(options);
  const Dataset dataset = ReadDataset(out / "kitti");
  EXPECT_EQ(dataset.ground.odometry.front().T.matrix(), Eigen::Matrix4d::Identity());
  EXPECT_TRUE(dataset.air.empty());
  EXPECT_FALSE(dataset.groundtruth.has_value());
}

TEST_F(KittiImportTest, PseudoAirAgentLivesInTheGivenWorld) {
  AG_REQUIRE_SHARED(drive, kDrive);
  Import(drive, PseudoAirOptions());
  const Dataset dataset = ReadDataset(*out_ / "kitti");
  const Pose T_wa_wg_expected = MakePose4Dof(-5.0, 2.5, 1.25, 30.0 * M_PI / 180.0);
  ASSERT_TRUE(dataset.groundtruth.has_value());
  ASSERT_EQ(dataset.groundtruth->T_wa_wg.count("kitti_air"), 1u);
  EXPECT_EQ(dataset.groundtruth->T_wa_wg.at("kitti_air").matrix(), T_wa_wg_expected.matrix());

  const AgentData& air = dataset.air.at("kitti_air");
  ASSERT_EQ(air.odometry.size(), dataset.ground.odometry.size());
  ASSERT_EQ(air.groundtruth.size(), dataset.ground.odometry.size());
  for (size_t i = 0; i < air.odometry.size(); ++i) {
    const Pose expected = T_wa_wg_expected * dataset.ground.odometry[i].T;
    EXPECT_EQ(air.odometry[i].t_ns, dataset.ground.odometry[i].t_ns);
    EXPECT_LT(MaxAbsDiff(air.odometry[i].T, expected), 1e-12) << i;
    EXPECT_LT(MaxAbsDiff(air.groundtruth[i].T, expected), 1e-12) << i;
  }
  // image_03's own timestamps and images.
  const std::vector<int64_t> listed = ReadKittiTimestamps(drive + "/image_03/timestamps.txt");
  EXPECT_EQ(air.images.front().t_ns, listed.front());
  EXPECT_FALSE(air.calibration.lidar.has_value());

  // Camera 3 sits 0.54 m to the right of camera 2 (KITTI's colour stereo
  // baseline, from P_rect_02 / P_rect_03), same orientation.
  const Pose T_c2_c3 = dataset.ground.calibration.camera.T_body_camera.inverse() *
                       air.calibration.camera.T_body_camera;
  EXPECT_LT((T_c2_c3.linear() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(T_c2_c3.translation().x(), 0.5327, 0.002);
  EXPECT_LT(std::abs(T_c2_c3.translation().y()), 0.01);
  EXPECT_LT(std::abs(T_c2_c3.translation().z()), 0.01);
  std::printf("camera 2 -> camera 3 in camera 2: %.4f %.4f %.4f m\n", T_c2_c3.translation().x(),
              T_c2_c3.translation().y(), T_c2_c3.translation().z());
}

TEST_F(KittiImportTest, CalibrationIsTheRectifiedPinhole) {
  AG_REQUIRE_SHARED(drive, kDrive);
  Import(drive, PseudoAirOptions());
  const Dataset dataset = ReadDataset(*out_ / "kitti");
  const CameraParams& camera = dataset.ground.calibration.camera.camera;
  EXPECT_EQ(camera.model, "pinhole");
  EXPECT_EQ(camera.width, 1242);
  EXPECT_EQ(camera.height, 375);
  EXPECT_EQ(camera.fx, 721.5377);
  EXPECT_EQ(camera.fy, 721.5377);
  EXPECT_EQ(camera.cx, 609.5593);
  EXPECT_EQ(camera.cy, 172.854);
  EXPECT_TRUE(camera.distortion.empty());
  const cv::Mat image = LoadImage(dataset.ground.images.front());
  EXPECT_EQ(image.cols, camera.width);
  EXPECT_EQ(image.rows, camera.height);
  // The camera looks along the IMU's forward axis (x) with x right (-y).
  const Eigen::Matrix3d R = dataset.ground.calibration.camera.T_body_camera.linear();
  EXPECT_GT(R.col(2).dot(Eigen::Vector3d::UnitX()), 0.999);
  EXPECT_GT(R.col(0).dot(-Eigen::Vector3d::UnitY()), 0.999);
  // Scans keep every Velodyne point and its reflectance.
  const PointCloud scan = ReadScan(dataset.ground.scans.front().path);
  const PointCloud raw = ReadKittiVelodyne(drive + "/velodyne_points/data/0000000000.bin");
  ASSERT_EQ(scan.points.size(), raw.points.size());
  EXPECT_EQ(scan.points[1000], raw.points[1000]);
  EXPECT_EQ(scan.intensity, raw.intensity);
}

TEST_F(KittiImportTest, LidarDepthEdgesLandOnImageEdges) {
  AG_REQUIRE_SHARED(drive, kDrive);
  Import(drive, PseudoAirOptions());
  const Dataset dataset = ReadDataset(*out_ / "kitti");
  const AgentCalibration& calibration = dataset.ground.calibration;
  ASSERT_TRUE(calibration.lidar.has_value());
  const Pose T_camera_lidar =
      calibration.camera.T_body_camera.inverse() * calibration.lidar->T_body_lidar;
  const Alignment imported = MeasureAlignment(dataset, T_camera_lidar);
  ASSERT_GT(imported.edge_points, 800u);

  // Perturbations in the camera frame (yaw = about the camera's y axis) and
  // the least ratio imported / perturbed of the on-edge fraction asserted.
  // 10 cm is 3-7 px at the 10-25 m of most contours; a vertical shift moves
  // points along the (mostly vertical) contours, so it is only printed.
  struct Perturbation {
    const char* what;
    Pose T_camera_lidar;
    double min_ratio;
  };
  const Pose T_c3_lidar = dataset.air.at("kitti_air").calibration.camera.T_body_camera.inverse() *
                          calibration.lidar->T_body_lidar;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  const std::vector<Perturbation> perturbations = {
      {"yaw +2 deg", CameraRotation(y, 2.0) * T_camera_lidar, 1.3},
      {"yaw -2 deg", CameraRotation(y, -2.0) * T_camera_lidar, 1.3},
      {"pitch +2 deg", CameraRotation(x, 2.0) * T_camera_lidar, 1.3},
      {"pitch -2 deg", CameraRotation(x, -2.0) * T_camera_lidar, 1.3},
      {"x +10 cm", CameraShift(0.10 * x) * T_camera_lidar, 1.2},
      {"x -10 cm", CameraShift(-0.10 * x) * T_camera_lidar, 1.2},
      {"y +10 cm", CameraShift(0.10 * y) * T_camera_lidar, 0.0},
      {"y -10 cm", CameraShift(-0.10 * y) * T_camera_lidar, 0.0},
      {"image_03's T_body_camera", T_c3_lidar, 1.3},
  };
  std::printf("LiDAR depth edges projected into image_02 (%zu depth-edge points, 5 frames)\n",
              imported.edge_points);
  std::printf("%-26s %8s %8s %13s %8s\n", "extrinsic", "on edge", "ratio", "mean gradient",
              "ratio");
  std::printf("%-26s %8.3f %8s %13.2f %8s\n", "imported", imported.on_image_edge, "",
              imported.mean_gradient, "");
  for (const Perturbation& p : perturbations) {
    const Alignment perturbed = MeasureAlignment(dataset, p.T_camera_lidar);
    const double ratio = imported.on_image_edge / perturbed.on_image_edge;
    const double gradient_ratio = imported.mean_gradient / perturbed.mean_gradient;
    std::printf("%-26s %8.3f %8.2f %13.2f %8.2f\n", p.what, perturbed.on_image_edge, ratio,
                perturbed.mean_gradient, gradient_ratio);
    if (p.min_ratio > 0) {
      EXPECT_GT(ratio, p.min_ratio) << p.what;
      EXPECT_GT(gradient_ratio, 1.0) << p.what;
    }
  }
}

}  // namespace
}  // namespace ag
