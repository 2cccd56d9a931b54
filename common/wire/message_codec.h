#pragma once

// Conversions between the core structs and the other LCM messages (camera
// info, relative pose, UGV/UAV sensor streams). Decoders validate and return
// a reason instead of throwing: daemons count and log bad messages.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "common/camera/camera_params.h"
#include "common/geometry/pose.h"
#include "lcmtypes/aglcm/camera_info_t.hpp"
#include "lcmtypes/aglcm/image_t.hpp"
#include "lcmtypes/aglcm/odometry_t.hpp"
#include "lcmtypes/aglcm/point_cloud_t.hpp"
#include "lcmtypes/aglcm/relative_pose_t.hpp"

namespace ag {

/// A camera as camera_info describes it.
struct CameraInfo {
  std::string agent;
  std::string camera_id;
  CameraParams params;
  bool has_T_body_camera = false;
  Pose T_body_camera = Pose::Identity();
  double time_offset_s = 0;
};

/// Validates a camera_info (the model must make a valid ag::Camera). Returns
/// false with `error` set otherwise.
bool DecodeCameraInfo(const aglcm::camera_info_t& msg, CameraInfo* info, std::string* error);

/// The relative-pose output of the ground server for one air agent.
struct RelativePoseEstimate {
  std::string agent;
  std::string ground_agent = "ground";
  int64_t seq = 0;
  int64_t t_ns = 0;
  int64_t air_t_ns = 0;
  int64_t air_seq = 0;
  int8_t status = aglcm::relative_pose_t::INITIALIZING;
  std::string status_reason;
  Pose T_wa_wg = Pose::Identity();  ///< 4-DoF
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  int num_inliers = 0;
  int num_keyframe_pairs = 0;
  double rms_reprojection_error_px = 0;
  double latency_s = 0;
  double solve_time_s = 0;
};
aglcm::relative_pose_t EncodeRelativePose(const RelativePoseEstimate& estimate);
bool DecodeRelativePose(const aglcm::relative_pose_t& msg, RelativePoseEstimate* out,
                        std::string* error);

/// Odometry pose T_world_body at t_ns. Decoding rejects non-finite values
/// and non-unit quaternions.
aglcm::odometry_t EncodeOdometry(const StampedPose& pose, const std::string& world_frame,
                                 const std::string& body_frame);
bool DecodeOdometry(const aglcm::odometry_t& msg, StampedPose* pose, std::string* error);

/// Images travel as PNG (lossless) or raw mono8/bgr8/rgb8.
aglcm::image_t EncodeImagePng(int64_t t_ns, const std::string& frame_id, const cv::Mat& image);
bool DecodeImage(const aglcm::image_t& msg, cv::Mat* image, std::string* error);

/// Point clouds in the sensor frame.
aglcm::point_cloud_t EncodePointCloud(int64_t t_ns, const std::string& frame_id,
                                      const std::vector<Eigen::Vector3f>& points,
                                      const std::vector<float>& intensity);
bool DecodePointCloud(const aglcm::point_cloud_t& msg, std::vector<Eigen::Vector3f>* points,
                      std::vector<float>* intensity, std::string* error);

}  // namespace ag
