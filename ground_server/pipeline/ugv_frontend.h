#pragma once

// Turns UGV sensor data into what the estimator consumes: camera images into
// UgvKeyframes (features, global descriptor, camera pose from LIO, 3-D points
// from the LiDAR map) and scans into posed scans for the map. Callable
// without threads; the daemon and the offline evaluator both use it.

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/camera/camera.h"
#include "common/dataset/dataset.h"
#include "common/features/feature_extractor.h"
#include "common/features/global_descriptor.h"
#include "ground_server/depth/depth_association.h"
#include "ground_server/estimation/agent_estimator.h"
#include "ground_server/odometry/odometry_buffer.h"
#include "ground_server/voxel_map/local_plane.h"
#include "ground_server/voxel_map/voxel_map.h"
#include "ground_server/voxel_map/voxel_map_builder.h"

namespace ag {

class UgvFrontend {
 public:
  struct Options {
    DepthAssociator::Options depth;
    double min_depth_fraction = 0.05;  ///< warn-level: fewer keypoints with depth than this
    bool fit_planes = true;            ///< map surface per keypoint (stage 1 anchors points to it)
    LocalPlaneOptions plane;
    /// The camera's motion (for the time-offset estimate) is a central
    /// difference of LIO poses over +-this (s); images wait this long for
    /// the odometry to pass them. 0.02 s follows the vehicle's vibration,
    /// where 0.1 s averages it out, and gave a 4-10x more exact offset
    /// (tools/evaluation/ACCURACY.md); with EstimatorOptions::max_air_span_s it gave
    /// better fixes on both simulated presets.
    double twist_half_window_s = 0.02;

    template <class V>
    void VisitFields(V& v) {
      v("depth", depth);
      v("min_depth_fraction", min_depth_fraction);
      v("fit_planes", fit_planes);
      v("plane", plane);
      v("twist_half_window_s", twist_half_window_s);
    }
    void Check() const;
  };

  struct Result {
    PoseLookupStatus status = PoseLookupStatus::kWait;  ///< kOk: keyframe is set
    std::shared_ptr<UgvKeyframe> keyframe;
    double features_ms = 0;
    double global_ms = 0;
    double depth_ms = 0;
  };

  /// `calibration` is the ground agent's (camera and LiDAR mounts). The
  /// extractors are shared with other users and must outlive this object.
  UgvFrontend(const AgentCalibration& calibration, const FeatureExtractor* features,
              const GlobalDescriptorExtractor* global, const Options& options);

  /// A keyframe from the image taken at t_camera_ns. status kWait when the
  /// odometry does not reach the image time yet, kRefuse when it never will.
  Result Process(int64_t id, int64_t t_camera_ns, const cv::Mat& image,
                 const OdometryBuffer& odometry, const VoxelMap& map) const;

  /// Whether the image at t_camera_ns can be processed: kWait until the
  /// odometry reaches options.twist_half_window_s past it (the camera's
  /// motion is a central difference over that window, for the time-offset
  /// estimate), kRefuse when its pose never will be known.
  PoseLookupStatus ImageReady(int64_t t_camera_ns, const OdometryBuffer& odometry) const;

  /// The scan at t_lidar_ns posed in the ground world, or the lookup status.
  PoseLookupStatus PoseScan(int64_t t_lidar_ns, std::vector<Eigen::Vector3f> points_l,
                            const OdometryBuffer& odometry, PosedScan* scan) const;

  const std::shared_ptr<const Camera>& camera() const { return camera_; }

 private:
  SensorMount camera_mount_;
  SensorMount lidar_mount_;
  std::shared_ptr<const Camera> camera_;
  const FeatureExtractor* features_;
  const GlobalDescriptorExtractor* global_;
  Options options_;
  DepthAssociator depth_;
};

/// The place database as the estimator's source of UAV keyframes.
class PlaceDb;
class PlaceDbSource : public AirKeyframeSource {
 public:
  explicit PlaceDbSource(const PlaceDb* db) : db_(db) {}
  std::vector<Candidate> Retrieve(const std::vector<float>& global, const std::string& agent,
                                  int k) const override;
  std::vector<std::shared_ptr<const AirKeyframe>> Recent(const std::string& agent,
                                                         int n) const override;

 private:
  const PlaceDb* db_;
};

}  // namespace ag
