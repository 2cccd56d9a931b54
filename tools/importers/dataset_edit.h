#pragma once

// Editing existing datasets (format v1, ../shared/spec/dataset.md), for
// importers of sources that have no ground agent (EuRoC MAV): start a new
// dataset from another one's ground agent, and add an air agent to a
// dataset. DatasetWriter only creates datasets from scratch; these reuse
// its file writers and leave what they did not change byte-identical.

#include <optional>
#include <string>
#include <vector>

#include "common/dataset/dataset.h"
#include "common/geometry/pose.h"

namespace ag {

/// Creates the dataset `out_dir` (must not exist or be empty) holding a copy
/// of the ground agent of the dataset `source_dir` (calibration, images,
/// scans, odometry, ground-truth trajectory; files are copied byte for byte
/// and renamed "<t_ns><ext>" as DatasetWriter names them) and no air agent.
/// The source is validated with ReadDataset first (throws its InputError).
void CopyGroundAgent(const std::string& source_dir, const std::string& out_dir,
                     const std::string& name, const std::string& description);

/// An air agent to add: images are copied from `images[i].path` and named
/// "<t_ns><ext of the source>".
struct AirAgentContent {
  AgentCalibration calibration;          ///< no lidar
  std::vector<SensorFrame> images;       ///< sorted by t_ns; path = source file
  std::vector<StampedPose> odometry;     ///< T_wa_body
  std::vector<StampedPose> groundtruth;  ///< optional (empty: no groundtruth.tum)
};

/// Adds air/<agent>/ to the existing dataset `dataset_dir` (validated with
/// ReadDataset before and after). The folder is written under a hidden name
/// (which readers ignore) and renamed when complete, so a failure leaves the
/// dataset as it was. With `T_wa_wg`, groundtruth.yaml gets (or replaces) the
/// agent's entry, keeping the rest; without, groundtruth.yaml is untouched.
/// Throws std::invalid_argument for an invalid or existing agent name,
/// InputError for bad input (the dataset, unsorted frames or poses, a
/// missing image).
void AddAirAgent(const std::string& dataset_dir, const std::string& agent,
                 const AirAgentContent& content, const std::optional<Pose>& T_wa_wg);

}  // namespace ag
