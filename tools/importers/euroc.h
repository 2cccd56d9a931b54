#pragma once

// EuRoC MAV dataset (Burri et al., "The EuRoC micro aerial vehicle
// datasets", IJRR 2016), ASL folder layout:
//   <sequence>/mav0/cam0/{sensor.yaml, data.csv, data/*.png}
//   <sequence>/mav0/state_groundtruth_estimate0/data.csv
// -> one air agent of a dataset (format v1, ../shared/spec/dataset.md).
// EuRoC has no ground agent and a dataset needs exactly one (ReadDataset
// requires ground/), so the air agent is added to an existing dataset
// (`into`) or to a new one started from another dataset's ground agent
// (`out_dir` + `ground_from`).

#include <cstdint>
#include <string>
#include <vector>

#include "common/dataset/dataset.h"
#include "common/geometry/pose.h"

namespace ag {

/// Reads a camera's sensor.yaml: T_BS (sensor pose in the body = IMU frame,
/// a 4x4 row-major `data:` list, so T_body_camera = T_BS), resolution,
/// camera_model (pinhole), intrinsics [fu, fv, cu, cv], distortion_model
/// (radial-tangential -> "pinhole", equidistant -> "equidistant") and
/// distortion_coefficients. The rotation of T_BS must be orthonormal to
/// 1e-6 and is replaced by the nearest rotation. Throws InputError naming
/// file, line and key; OptionError-derived camera problems come back as
/// InputError(kBadValue) naming the file.
AgentCalibration ReadEurocCamera(const std::string& sensor_yaml);

/// Reads state_groundtruth_estimate0/data.csv: "#timestamp, p_RS_R_x,
/// p_RS_R_y, p_RS_R_z, q_RS_w, q_RS_x, q_RS_y, q_RS_z, ..." (w first; the
/// velocity and bias columns after them are ignored) as T_R_S poses, where S
/// is the body (IMU) and R the gravity-aligned reference frame. Quaternions
/// off unit norm by more than 1e-3 are rejected, the others normalised.
/// Throws InputError naming file and line.
std::vector<StampedPose> ReadEurocGroundTruth(const std::string& csv_path);

/// The mav0 folder: `input` itself when it holds the camera folders, else
/// `input`/mav0. Throws InputError(kMissingFile) otherwise.
std::string FindEurocMav(const std::string& input);

/// Adds a 4-DoF random-walk drift to a trajectory, as VIO drifts in x, y,
/// z and yaw: T_odom(t) = D(t) * T(t) with D(t0) = I and independent
/// Gaussian increments of standard deviation sigma * sqrt(dt) per axis.
/// Deterministic for a seed. Sigmas 0 return the input unchanged.
std::vector<StampedPose> AddRandomWalkDrift(const std::vector<StampedPose>& poses,
                                            double sigma_m_per_sqrt_s,
                                            double sigma_yaw_rad_per_sqrt_s, uint64_t seed);

struct EurocImportOptions {
  std::string input;            ///< EuRoC sequence folder (holding mav0/) or mav0 itself
  std::string camera = "cam0";  ///< camera folder of mav0
  std::string agent = "euroc";  ///< air agent name ([a-z0-9_]+)
  std::string into;             ///< add the agent to this existing dataset, or ...
  std::string out_dir;          ///< ... create this new dataset ...
  std::string ground_from;      ///< ... with the ground agent copied from this dataset
  std::string name;             ///< name of a new dataset; empty: the sequence folder's name
  /// T_wa_wg written to groundtruth.yaml: x, y, z (m), yaw (deg); empty:
  /// groundtruth.yaml is not touched (EuRoC alone knows no such transform).
  std::vector<double> air_offset;
  double drift_m_per_sqrt_s = 0.0;        ///< odometry random-walk drift, x y z (m/sqrt(s))
  double drift_yaw_deg_per_sqrt_s = 0.0;  ///< odometry random-walk drift, yaw (deg/sqrt(s))
  int64_t seed = 1;                       ///< random seed of the drift

  template <class V>
  void VisitFields(V& v) {
    v("input", input);
    v("camera", camera);
    v("agent", agent);
    v("into", into);
    v("out_dir", out_dir);
    v("ground_from", ground_from);
    v("name", name);
    v("air_offset", air_offset);
    v("drift_m_per_sqrt_s", drift_m_per_sqrt_s);
    v("drift_yaw_deg_per_sqrt_s", drift_yaw_deg_per_sqrt_s);
    v("seed", seed);
  }
  void Check() const;
};

struct EurocImportSummary {
  std::string dataset_dir;  ///< the dataset the agent was added to
  std::string agent;
  size_t images = 0;
  size_t poses = 0;
  size_t images_outside_groundtruth = 0;  ///< EuRoC's cameras start before its ground truth
};

/// Imports one camera and the ground-truth estimate as air agent
/// options.agent: calibration from sensor.yaml, groundtruth.tum from the
/// ground-truth estimate, odometry.tum equal to it or with a random-walk
/// drift. Images are copied byte for byte. Throws InputError on bad input,
/// OptionError on bad options, std::invalid_argument when the agent exists.
EurocImportSummary ImportEuroc(const EurocImportOptions& options);

}  // namespace ag
