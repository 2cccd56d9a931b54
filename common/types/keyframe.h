#pragma once

// Plain structs exchanged between the feature extractor, the wire codec, the
// place database and the estimator. They know nothing about LCM: only the
// adapter in common/wire converts them to and from packets.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "common/camera/camera_params.h"
#include "common/geometry/pose.h"

namespace ag {

/// Keypoints and local descriptors of one image.
struct LocalFeatures {
  std::vector<Eigen::Vector2f> keypoints;  ///< pixel coordinates (x right, y down), px
  std::vector<float> scores;               ///< detector score per keypoint, higher is better
  cv::Mat descriptors;                     ///< N x dim, CV_32F, each row L2-normalised
  std::string descriptor_type;             ///< "xfeat" or "sift"; matching needs equal types

  size_t size() const { return keypoints.size(); }
  int dim() const { return descriptors.cols; }
};

/// One UAV keyframe as the ground side receives it (after decoding).
struct AirKeyframe {
  std::string agent;               ///< air agent name ([a-z0-9_]+)
  int64_t seq = 0;                 ///< per-agent sequence number, increasing
  int64_t t_ns = 0;                ///< image time in the air clock (ns)
  std::string camera_id;           ///< which camera_info describes the pixels
  Pose T_wa_c = Pose::Identity();  ///< camera pose in the air world (from VIO)
  LocalFeatures features;
  std::vector<float> global_descriptor;  ///< L2-normalised place descriptor (512-D default)
};

}  // namespace ag
