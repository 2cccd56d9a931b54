#include "common/wire/message_codec.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

namespace ag {
namespace {

aglcm::camera_info_t GoodCameraInfo() {
  aglcm::camera_info_t m;
  m.agent = "uav_1";
  m.camera_id = "cam0";
  m.t_ns = 5;
  m.model = "pinhole";
  m.width = 640;
  m.height = 480;
  m.intrinsics[0] = m.intrinsics[1] = 500;
  m.intrinsics[2] = 320;
  m.intrinsics[3] = 240;
  m.distortion = {-0.1, 0.01, 0.0, 0.0};
  m.num_distortion = 4;
  m.has_T_body_camera = true;
  const Eigen::Matrix4d T = MakePose4Dof(0.1, 0, -0.05, 0.3).matrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m.T_body_camera[r][c] = T(r, c);
  }
  m.time_offset_s = 0.012;
  return m;
}

TEST(MessageCodecTest, CameraInfoValidatesTheModel) {
  CameraInfo info;
  std::string error;
  ASSERT_TRUE(DecodeCameraInfo(GoodCameraInfo(), &info, &error)) << error;
  EXPECT_EQ(info.params.distortion.size(), 4u);
  EXPECT_NEAR(info.T_body_camera.translation().x(), 0.1, 1e-15);
  EXPECT_DOUBLE_EQ(info.time_offset_s, 0.012);
  auto bad = GoodCameraInfo();
  bad.model = "fisheye-ish";
  EXPECT_FALSE(DecodeCameraInfo(bad, &info, &error));
  EXPECT_NE(error.find("model"), std::string::npos) << error;
  bad = GoodCameraInfo();
  bad.intrinsics[0] = NAN;
  EXPECT_FALSE(DecodeCameraInfo(bad, &info, &error));
  bad = GoodCameraInfo();
  bad.T_body_camera[0][0] = 2;
  EXPECT_FALSE(DecodeCameraInfo(bad, &info, &error));
  EXPECT_NE(error.find("T_body_camera"), std::string::npos);
  bad = GoodCameraInfo();
  bad.num_distortion = 5;
  EXPECT_FALSE(DecodeCameraInfo(bad, &info, &error));
}

TEST(MessageCodecTest, RelativePoseRoundTrip) {
  RelativePoseEstimate e;
  e.agent = "uav_1";
  e.seq = 3;
  e.t_ns = 100;
  e.air_t_ns = 90;
  e.air_seq = 7;
  e.status = aglcm::relative_pose_t::TRACKING;
  e.status_reason = "ok";
  e.T_wa_wg = MakePose4Dof(1, -2, 0.5, 2.5);
  e.covariance = Eigen::Vector4d(1e-4, 2e-4, 3e-4, 1e-6).asDiagonal();
  e.num_inliers = 321;
  const aglcm::relative_pose_t m = EncodeRelativePose(e);
  EXPECT_NEAR(m.yaw, 2.5, 1e-12);
  EXPECT_NEAR(m.T_wa_wg[0][3], 1, 1e-12);
  EXPECT_NEAR(m.T_wa_wg[1][0], std::sin(2.5), 1e-12);
  RelativePoseEstimate back;
  std::string error;
  ASSERT_TRUE(DecodeRelativePose(m, &back, &error)) << error;
  EXPECT_TRUE(back.T_wa_wg.matrix().isApprox(e.T_wa_wg.matrix(), 1e-12));
  EXPECT_EQ(back.covariance, e.covariance);
  EXPECT_EQ(back.num_inliers, 321);
  auto bad = m;
  bad.status = 9;
  EXPECT_FALSE(DecodeRelativePose(bad, &back, &error));
}

TEST(MessageCodecTest, OdometryRejectsNanAndNonUnitQuaternions) {
  const StampedPose p{42, MakePose4Dof(1, 2, 3, 0.4)};
  aglcm::odometry_t m = EncodeOdometry(p, "wg", "body");
  StampedPose back;
  std::string error;
  ASSERT_TRUE(DecodeOdometry(m, &back, &error));
  EXPECT_EQ(back.t_ns, 42);
  EXPECT_TRUE(back.T.matrix().isApprox(p.T.matrix(), 1e-12));
  m.position[2] = NAN;
  EXPECT_FALSE(DecodeOdometry(m, &back, &error));
  m = EncodeOdometry(p, "wg", "body");
  m.orientation[0] = 0.2;
  EXPECT_FALSE(DecodeOdometry(m, &back, &error));
}

TEST(MessageCodecTest, ImagesRoundTripAndBadOnesAreRejected) {
  cv::Mat img(48, 64, CV_8UC3);
  cv::randu(img, 0, 255);
  cv::Mat back;
  std::string error;
  ASSERT_TRUE(DecodeImage(EncodeImagePng(7, "cam0", img), &back, &error)) << error;
  EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0.0);
  aglcm::image_t raw;
  raw.t_ns = 1;
  raw.width = 64;
  raw.height = 48;
  raw.encoding = "mono8";
  raw.step = 64;
  raw.data.assign(64 * 48, 7);
  raw.num_bytes = static_cast<int>(raw.data.size());
  ASSERT_TRUE(DecodeImage(raw, &back, &error)) << error;
  EXPECT_EQ(back.at<uint8_t>(10, 10), 7);
  raw.height = 49;  // data too short
  EXPECT_FALSE(DecodeImage(raw, &back, &error));
  raw.height = 48;
  raw.encoding = "yuv422";
  EXPECT_FALSE(DecodeImage(raw, &back, &error));
  EXPECT_NE(error.find("unknown encoding"), std::string::npos);
  auto png = EncodeImagePng(7, "cam0", img);
  png.data.resize(20);
  png.num_bytes = 20;
  EXPECT_FALSE(DecodeImage(png, &back, &error));
}

TEST(MessageCodecTest, PointCloudsDropNanPointsKeepingIntensityAligned) {
  std::vector<Eigen::Vector3f> pts = {{1, 2, 3}, {NAN, 0, 0}, {4, 5, 6}};
  aglcm::point_cloud_t m = EncodePointCloud(3, "lidar", pts, {0.1f, 0.2f, 0.3f});
  std::vector<Eigen::Vector3f> back;
  std::vector<float> intensity;
  std::string error;
  ASSERT_TRUE(DecodePointCloud(m, &back, &intensity, &error));
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_EQ(intensity, (std::vector<float>{0.1f, 0.3f}));
  m.num_points = 4;
  EXPECT_FALSE(DecodePointCloud(m, &back, &intensity, &error));
}

}  // namespace
}  // namespace ag
