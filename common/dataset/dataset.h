#pragma once

// Reader and writer of the on-disk dataset format, version 1
// (../shared/spec/dataset.md). Readers validate everything they index and
// throw ag::InputError naming file, line and problem; pixels and point
// clouds are loaded lazily (LoadImage here, ReadScan in common/pcd).

#include <cstdint>
#include <map>
#include <opencv2/core/mat.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/camera/camera_params.h"
#include "common/core/agent_name.h"
#include "common/geometry/pose.h"

namespace ag {

/// Nominal calibration of one agent (calibration.yaml).
struct CameraCalibration {
  CameraParams camera;
  Pose T_body_camera = Pose::Identity();
  double time_offset_s = 0.0;  ///< t_body = t_camera + time_offset_s
};

struct LidarCalibration {
  Pose T_body_lidar = Pose::Identity();
  double time_offset_s = 0.0;  ///< t_body = t_lidar + time_offset_s
};

struct AgentCalibration {
  CameraCalibration camera;
  std::optional<LidarCalibration> lidar;  ///< ground agent only
};

/// One row of images.csv or scans.csv.
struct SensorFrame {
  int64_t t_ns = 0;      ///< sensor clock (ns)
  std::string filename;  ///< relative to images/ or scans/
  std::string path;      ///< absolute (or dataset-relative) path, filled by the reader
};

/// One agent's folder (ground/ or air/<name>/).
struct AgentData {
  std::string name;  ///< "ground" or the air agent name
  std::string dir;   ///< the agent's folder
  AgentCalibration calibration;
  std::vector<SensorFrame> images;
  std::vector<SensorFrame> scans;        ///< ground only
  std::vector<StampedPose> odometry;     ///< T_world_body (LIO or VIO)
  std::vector<StampedPose> groundtruth;  ///< empty when groundtruth.tum is absent
};

/// groundtruth.yaml (evaluation only: no estimator may read it).
struct DatasetGroundTruth {
  std::map<std::string, Pose> T_wa_wg;  ///< per air agent
  /// Optional diagnostics written by simulators (true_calibration). Only
  /// T_body_camera and time_offset_s (camera_time_offset_s in the file) of
  /// the camera entries are stored; `camera` (intrinsics) is left default.
  std::optional<CameraCalibration> ground_true_camera;
  /// Only T_body_lidar: the format has no true lidar time offset, so the
  /// writer refuses a non-zero time_offset_s here and the reader leaves 0.
  std::optional<LidarCalibration> ground_true_lidar;
  std::map<std::string, CameraCalibration> air_true_camera;
};

struct Dataset {
  std::string dir;
  int format_version = 1;
  std::string name;
  std::string description;
  AgentData ground;
  std::map<std::string, AgentData> air;  ///< by agent name, sorted
  std::optional<DatasetGroundTruth> groundtruth;
};

/// Reads and validates a whole dataset (every CSV, TUM and YAML file; that
/// every listed image and scan file exists). Throws ag::InputError naming
/// file, line and problem. Required: dataset.yaml, ground/ with
/// calibration.yaml (with lidar), images.csv, images/, scans.csv, scans/,
/// odometry.tum; per air agent calibration.yaml, images.csv, images/,
/// odometry.tum. Optional: air/ (no air agent), groundtruth.yaml and every
/// groundtruth.tum. Entries of air/ starting with '.' are ignored; any other
/// entry must be a folder named [a-z0-9_]+.
Dataset ReadDataset(const std::string& dir);

/// Reads one calibration.yaml. `require_lidar` for the ground agent.
/// Unknown keys are rejected (typo guard); time_offset_s defaults to 0 and
/// distortion to [] when absent; the camera is validated as ag::Camera does.
AgentCalibration ReadCalibration(const std::string& path, bool require_lidar);

/// Reads images.csv / scans.csv (EuRoC style: '#' lines are comments, rows
/// "t_ns,filename", spaces around fields and CRLF tolerated); checks strictly
/// increasing timestamps and that the files exist below `data_dir`.
std::vector<SensorFrame> ReadFrameList(const std::string& csv_path, const std::string& data_dir);

/// Reads groundtruth.yaml (standalone: agent names are checked for syntax
/// only; ReadDataset also checks they are agents of the dataset).
DatasetGroundTruth ReadGroundTruth(const std::string& path);

/// The folder of an agent: <dataset>/ground for "ground", else
/// <dataset>/air/<agent>.
std::string AgentDir(const std::string& dataset_dir, const std::string& agent);

/// Loads the pixels of one images.csv row with cv::imread(frame.path, flags).
/// Throws InputError(kMissingFile) naming the path when the file is missing
/// or not a readable image, and InputError(kBadValue) when it is not 8-bit.
cv::Mat LoadImage(const SensorFrame& frame, int flags = cv::IMREAD_UNCHANGED);

/// Writes a dataset incrementally. Creates the folder layout on Begin*,
/// records rows as frames are added, and writes the CSV/TUM/YAML files on
/// Finish(). The caller writes each image (cv::imwrite) or scan
/// (ag::WriteScan) at the path AddImage / AddScan returns. Misuse (unknown
/// agent, invalid name, a second Begin*) throws std::invalid_argument; an
/// invalid calibration throws ag::OptionError naming the field.
class DatasetWriter {
 public:
  /// Creates `dir` (must not exist or be empty) and dataset.yaml.
  DatasetWriter(const std::string& dir, const std::string& name, const std::string& description);

  /// Declares the ground agent (its calibration must have a lidar) / an air
  /// agent (name [a-z0-9_]+, not "ground") with its nominal calibration.
  void BeginGround(const AgentCalibration& calibration);
  void BeginAir(const std::string& agent, const AgentCalibration& calibration);

  /// Path where the caller writes the image / PCD for a frame (the writer
  /// records the row). `agent` is "ground" or an air agent name; `ext`
  /// ".png", ".jpg" or ".jpeg" for images. File names are "<t_ns><ext>";
  /// scans are "<t_ns>.pcd".
  std::string AddImage(const std::string& agent, int64_t t_ns, const std::string& ext = ".png");
  std::string AddScan(int64_t t_ns);

  void SetOdometry(const std::string& agent, const std::vector<StampedPose>& poses);
  void SetGroundTruthTrajectory(const std::string& agent, const std::vector<StampedPose>& poses);
  void SetGroundTruth(const DatasetGroundTruth& groundtruth);

  /// Writes every index file (odometry.tum always, groundtruth.tum only when
  /// set and non-empty, groundtruth.yaml only when set). Throws
  /// InputError(kUnsorted) naming the file and line when frames or poses are
  /// not strictly increasing in time, InputError(kMissingFile) when a
  /// recorded image or scan was not written, std::logic_error without a
  /// ground agent or on a second call. Not called by the destructor.
  void Finish();

  const std::string& dir() const { return dir_; }

 private:
  struct AgentState {
    std::string dir;
    AgentCalibration calibration;
    std::vector<SensorFrame> images;
    std::vector<SensorFrame> scans;
    std::vector<StampedPose> odometry;
    std::vector<StampedPose> groundtruth;
  };
  AgentState& Agent(const std::string& agent);

  std::string dir_;
  std::map<std::string, AgentState> agents_;  ///< "ground" and air names
  std::optional<DatasetGroundTruth> groundtruth_;
  bool finished_ = false;
};

/// Writes calibration.yaml / groundtruth.yaml (also used by importers).
/// Numbers are written exactly (shortest text that reads back bit-equal,
/// at most 17 significant digits); 4x4 matrices row-major as lists of 4
/// lists. WriteCalibration validates the camera as ag::Camera does (throws
/// ag::OptionError). Both throw InputError(kMissingFile) when the file
/// cannot be written.
void WriteCalibration(const std::string& path, const AgentCalibration& calibration);
void WriteGroundTruth(const std::string& path, const DatasetGroundTruth& groundtruth);

}  // namespace ag
