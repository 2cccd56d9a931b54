#pragma once

// The evaluation report of ../shared/spec/report.md (field names kept
// exactly), built from what an evaluation run records.

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/dataset/ground_truth.h"
#include "common/geometry/pose.h"

namespace ag {

/// Order statistics of a sample (all zero when empty).
struct SampleStats {
  double median = 0, mean = 0, p95 = 0, max = 0;
  size_t count = 0;
};
SampleStats ComputeStats(std::vector<double> values);

/// Per air agent, what the run recorded.
struct AgentRecord {
  int64_t packets_sent = 0;
  int64_t bytes_sent = 0;        ///< LCM UDP payload bytes (what LCM puts on the link)
  int64_t bytes_ip = 0;          ///< with UDP/IP headers and IP fragmentation
  int64_t ip_packets = 0;        ///< IPv4 packets of the keyframe messages
  int64_t ip_packets_lost = 0;   ///< of those, lost (EvaluateOptions::link_loss)
  int64_t keyframes_stored = 0;  ///< UAV keyframes (joined from what arrived) in the database
  int64_t keypoints_stored = 0;  ///< their keypoints
  std::vector<std::pair<int64_t, int64_t>> packets;  ///< (t_ns, bytes) for bandwidth windows
  std::optional<int64_t> first_packet_t_ns;
  struct Fix {
    int64_t t_ns = 0;
    Pose T_wa_wg;
    std::optional<PoseError> error;  ///< when ground truth exists
    /// Against the relation of the two odometry worlds at the estimate's
    /// times (truth with the odometry drift of both agents applied): what the
    /// estimator could observe. Needs groundtruth.tum of both agents.
    std::optional<PoseError> drift_free_error;
    /// How far the fix maps the UGV camera's position from where that
    /// drift-free truth maps it (m): the error where the two vehicles work
    /// together. The translation of T_wa_wg is taken at the ground world's
    /// origin, where a yaw error moves it by the yaw times the distance.
    std::optional<double> drift_free_error_at_ugv_m;
    /// groundtruth.yaml against that drift-free truth: the error an estimate
    /// exactly equal to the odometry worlds' relation would have (an inexact
    /// one can land nearer or farther).
    std::optional<PoseError> truth_drift;
  };
  std::vector<Fix> fixes;  ///< published fixes only
  /// Rotation error (deg) of the UGV camera against the LiDAR map at the
  /// nominal calibration and after this agent's stage-1 correction, at the
  /// end of the run; when the dataset has the true calibrations.
  std::optional<std::pair<double, double>> ugv_camera_rotation_error_deg;
  /// The same for the camera's position (m). The calibrator
  /// (estimator.camera_rotation) corrects only the rotation, so by default
  /// both are equal; stage 1's fused window correction, used when the
  /// calibrator is off, moves the position too.
  std::optional<std::pair<double, double>> ugv_camera_translation_error_m;
  /// The UGV camera's time offset against LIO beyond the nominal
  /// calibration's (ms): the dataset's true one and this agent's stage-1
  /// estimate at the end of the run; when the dataset has the true
  /// calibrations.
  std::optional<std::pair<double, double>> ugv_camera_time_offset_ms;
};

/// Wall-clock samples, in ms.
struct TimingRecord {
  std::vector<double> estimate, stage1, stage2, retrieval, depth_association_per_keyframe,
      air_features_per_frame;
  std::vector<double> matching, ransac,
      stage1_tracking;  ///< beyond the spec: the rest of an estimate
};

struct ReportInput {
  std::string dataset;
  nlohmann::json config;  ///< the effective configuration
  std::map<std::string, AgentRecord> agents;
  TimingRecord timing;
  bool has_groundtruth = false;
  double success_translation_m = 0.3;  ///< final fix within this ...
  double success_yaw_deg = 3.0;        ///< ... and this, for success
  double false_fix_translation_m = 1.0;
  double false_fix_yaw_deg = 10.0;
};

/// Bandwidth over a run: mean over [first packet, last packet + 1 s) and
/// the largest sum in any 1 s window, in Mbit/s.
struct Bandwidth {
  double mean_mbps = 0;
  double max_1s_mbps = 0;
};
Bandwidth ComputeBandwidth(const std::vector<std::pair<int64_t, int64_t>>& packets);

/// A YAML tree (as the options write themselves) as JSON: maps, lists,
/// booleans, numbers where the scalar is one, strings otherwise.
nlohmann::json YamlToJson(const YAML::Node& node);

/// The report JSON (format_version 1).
nlohmann::json MakeReport(const ReportInput& input);

}  // namespace ag
