// Depth association on a real KITTI raw frame, compared with the direct
// projection of the same LiDAR scan into the image.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "ground_server/depth/depth_association.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

// A minimal reader for the two KITTI calibration files ("key: v1 v2 ...").
std::map<std::string, std::vector<double>> ReadKittiCalib(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::map<std::string, std::vector<double>> values;
  std::string line;
  while (std::getline(in, line)) {
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::istringstream fields(line.substr(colon + 1));
    std::vector<double> numbers;
    double x = 0;
    while (fields >> x) numbers.push_back(x);
    if (!fields.eof()) continue;  // calib_time and other text rows
    values[line.substr(0, colon)] = numbers;
  }
  return values;
}

std::vector<Eigen::Vector3f> ReadVelodyneBin(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  std::vector<Eigen::Vector3f> points;
  float xyzr[4];
  while (in.read(reinterpret_cast<char*>(xyzr), sizeof(xyzr))) {
    points.emplace_back(xyzr[0], xyzr[1], xyzr[2]);
  }
  return points;
}

// T_world_imu of an OXTS record, as the KITTI devkit computes it: Mercator
// position with the scale of the first record's latitude, R = Rz Ry Rx.
Pose OxtsPose(const std::string& path, double* mercator_scale) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  double lat = 0, lon = 0, alt = 0, roll = 0, pitch = 0, yaw = 0;
  in >> lat >> lon >> alt >> roll >> pitch >> yaw;
  if (*mercator_scale == 0) *mercator_scale = std::cos(lat * M_PI / 180.0);
  constexpr double kEarthRadius = 6378137.0;
  const double s = *mercator_scale;
  Pose T = Pose::Identity();
  T.translation() =
      Eigen::Vector3d(s * lon * M_PI * kEarthRadius / 180.0,
                      s * kEarthRadius * std::log(std::tan((90.0 + lat) * M_PI / 360.0)), alt);
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return T;
}

struct Agreement {
  size_t keypoints = 0;
  int with_direct = 0;
  size_t associated = 0;
  int only_association = 0;
  int both = 0;
  int agree = 0;
  double median_abs = 1e9;
  double median_rel = 1e9;
};

// Map = scans 0..num_scans-1 in the LiDAR frame of scan 0 (OXTS poses);
// keypoints = corners of image_02 frame 0. Direct reference = front-most
// depth of the same map points projected within 2 px of the keypoint.
void CompareOnKitti(const std::string& day, int num_scans, Agreement* out) {
  const std::string drive = day + "/2011_09_26_drive_0001_sync";
  const auto cam = ReadKittiCalib(day + "/calib_cam_to_cam.txt");
  const auto velo = ReadKittiCalib(day + "/calib_velo_to_cam.txt");
  ASSERT_EQ(cam.at("P_rect_02").size(), 12u);
  ASSERT_EQ(cam.at("R_rect_00").size(), 9u);
  ASSERT_EQ(velo.at("R").size(), 9u);
  ASSERT_EQ(velo.at("T").size(), 3u);

  // p_image2 ~ P_rect_02 * R_rect_00 * Tr_velo_to_cam * p_velo, with
  // P_rect_02 = K [I | t]: the rectified camera 2 sees p_c = R_rect p_cam0 + t.
  const Eigen::Matrix<double, 3, 4, Eigen::RowMajor> P(cam.at("P_rect_02").data());
  const Eigen::Matrix3d K = P.leftCols<3>();
  Pose T_c_rect0 = Pose::Identity();
  T_c_rect0.translation() = K.inverse() * P.col(3);
  Pose T_rect0_cam0 = Pose::Identity();
  T_rect0_cam0.linear() = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>(cam.at("R_rect_00").data());
  Pose T_cam0_velo = Pose::Identity();
  T_cam0_velo.linear() = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>(velo.at("R").data());
  T_cam0_velo.translation() = Eigen::Vector3d(velo.at("T").data());
  ASSERT_TRUE(IsRotation(T_rect0_cam0.linear(), 1e-5));
  ASSERT_TRUE(IsRotation(T_cam0_velo.linear(), 1e-5));
  const Pose T_c_velo = T_c_rect0 * T_rect0_cam0 * T_cam0_velo;
  const Pose T_wg_c = T_c_velo.inverse();  // world = the LiDAR frame of scan 0

  CameraParams params;
  params.width = static_cast<int>(cam.at("S_rect_02").at(0));
  params.height = static_cast<int>(cam.at("S_rect_02").at(1));
  params.fx = K(0, 0);
  params.fy = K(1, 1);
  params.cx = K(0, 2);
  params.cy = K(1, 2);
  const Camera camera(params);

  const cv::Mat image = cv::imread(drive + "/image_02/data/0000000000.png", cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(image.empty());
  ASSERT_EQ(image.cols, params.width);
  ASSERT_EQ(image.rows, params.height);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(image, corners, 1024, 0.005, 5);
  std::vector<Eigen::Vector2f> keypoints;
  keypoints.reserve(corners.size());
  for (const auto& c : corners) keypoints.emplace_back(c.x, c.y);
  ASSERT_GT(keypoints.size(), 500u);

  const auto imu = ReadKittiCalib(day + "/calib_imu_to_velo.txt");
  Pose T_velo_imu = Pose::Identity();
  T_velo_imu.linear() = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>(imu.at("R").data());
  T_velo_imu.translation() = Eigen::Vector3d(imu.at("T").data());
  double mercator_scale = 0;
  Pose T_velo0_w = Pose::Identity();
  std::vector<Eigen::Vector3f> scan;  // all scans, in the LiDAR frame of scan 0
  for (int k = 0; k < num_scans; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%010d", k);
    const Pose T_w_velo =
        OxtsPose(drive + "/oxts/data/" + name + ".txt", &mercator_scale) * T_velo_imu.inverse();
    if (k == 0) T_velo0_w = T_w_velo.inverse();
    const Eigen::Isometry3f T_velo0_velo = (T_velo0_w * T_w_velo).cast<float>();
    const auto points = ReadVelodyneBin(drive + "/velodyne_points/data/" + name + ".bin");
    ASSERT_GT(points.size(), 100000u);
    for (const auto& p : points) scan.push_back(T_velo0_velo * p);
  }

  // Direct projection: front-most LiDAR depth within 2 px of each keypoint.
  constexpr double kRadiusPx = 2.0;
  std::vector<double> direct(keypoints.size(), std::numeric_limits<double>::infinity());
  std::vector<std::vector<int>> grid(static_cast<size_t>(params.width * params.height));
  for (size_t i = 0; i < keypoints.size(); ++i) {
    grid[static_cast<int>(keypoints[i].y()) * params.width + static_cast<int>(keypoints[i].x())]
        .push_back(static_cast<int>(i));
  }
  for (const Eigen::Vector3f& p : scan) {
    const Eigen::Vector3d p_c = T_c_velo * p.cast<double>();
    Eigen::Vector2d uv;
    if (p_c.z() < 0.5 || !camera.Project(p_c, &uv) || !camera.InImage(uv)) continue;
    for (int y = static_cast<int>(uv.y() - kRadiusPx); y <= static_cast<int>(uv.y() + kRadiusPx);
         ++y) {
      for (int x = static_cast<int>(uv.x() - kRadiusPx); x <= static_cast<int>(uv.x() + kRadiusPx);
           ++x) {
        if (x < 0 || y < 0 || x >= params.width || y >= params.height) continue;
        for (int k : grid[y * params.width + x]) {
          if ((keypoints[k].cast<double>() - uv).norm() <= kRadiusPx) {
            direct[k] = std::min(direct[k], p_c.z());
          }
        }
      }
    }
  }

  VoxelGrid::Options map_options;
  map_options.max_points_per_voxel = 20;
  VoxelGrid map(map_options);
  map.Insert(scan, Eigen::Vector3d::Zero());
  DepthAssociator::Options options;
  options.max_range_m = 80.0;
  const DepthAssociator associator(camera, options);
  const DepthAssociationResult result = associator.Associate(map, T_wg_c, keypoints);
  const DepthAssociationResult reference = associator.AssociateReference(map, T_wg_c, keypoints);
  EXPECT_EQ(result.num_valid, reference.num_valid);

  int with_direct = 0, both = 0, agree = 0, only_association = 0;
  std::vector<double> abs_diff, rel_diff;
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const KeypointDepth& a = result.keypoints[i];
    ASSERT_EQ(a.valid, reference.keypoints[i].valid);
    if (a.valid) {
      ASSERT_EQ(a.p_in_wg, reference.keypoints[i].p_in_wg);
    }
    const bool has_direct = std::isfinite(direct[i]);
    with_direct += has_direct;
    only_association += a.valid && !has_direct;
    if (!a.valid || !has_direct) continue;
    ++both;
    const double diff = std::abs(a.depth_m - direct[i]);
    abs_diff.push_back(diff);
    rel_diff.push_back(diff / direct[i]);
    agree += diff <= std::max(0.1, 0.05 * direct[i]);
  }
  std::sort(abs_diff.begin(), abs_diff.end());
  std::sort(rel_diff.begin(), rel_diff.end());
  out->keypoints = keypoints.size();
  out->with_direct = with_direct;
  out->associated = result.num_valid;
  out->only_association = only_association;
  out->both = both;
  out->agree = agree;
  if (!abs_diff.empty()) {
    out->median_abs = abs_diff[abs_diff.size() / 2];
    out->median_rel = rel_diff[rel_diff.size() / 2];
  }
  std::printf(
      "KITTI 0001 frame 0, %d scan(s), %zu map points: %zu keypoints, %d with a map point within "
      "%.0f px, %zu given depth by association (%d without a direct point); on %d with both: "
      "median |dz| %.3f m, median relative %.2f%%, %.1f%% agree within max(0.1 m, 5%%); samples "
      "queried %zu, skipped %zu\n",
      num_scans, map.num_points(), keypoints.size(), with_direct, kRadiusPx, result.num_valid,
      only_association, both, out->median_abs, 100.0 * out->median_rel,
      100.0 * agree / std::max(both, 1), result.samples_queried, result.samples_skipped);
}

constexpr const char* kKittiDay = "data/kitti_raw_2011_09_26_drive_0001_mini/2011_09_26";

TEST(KittiDepthTest, SingleScanAssociationAgreesWithDirectProjection) {
  AG_REQUIRE_SHARED(day, kKittiDay);
  Agreement a;
  CompareOnKitti(day, 1, &a);
  ASSERT_GT(a.keypoints, 500u);
  EXPECT_GT(a.both, 0.9 * a.with_direct);
  EXPECT_LT(a.median_rel, 0.01);
  EXPECT_GT(a.agree, 0.95 * a.both);
}

TEST(KittiDepthTest, FiveScanMapAssociationAgreesWithDirectProjection) {
  AG_REQUIRE_SHARED(day, kKittiDay);
  Agreement a;
  CompareOnKitti(day, 5, &a);
  ASSERT_GT(a.keypoints, 500u);
  EXPECT_GT(a.both, 0.9 * a.with_direct);
  EXPECT_LT(a.median_rel, 0.01);
  EXPECT_GT(a.agree, 0.95 * a.both);
}

}  // namespace
}  // namespace ag
