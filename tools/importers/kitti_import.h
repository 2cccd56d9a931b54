#pragma once

// KITTI raw (synced + rectified) drive -> dataset format v1
// (../shared/spec/dataset.md): the ground agent from one colour camera, the
// Velodyne and OXTS poses, and optionally a pseudo air agent from the other
// colour camera in a world moved by a known 4-DoF T_wa_wg: a relative-
// localization problem with a known answer on real images and real LiDAR.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/geometry/pose.h"

namespace ag {

struct KittiImportOptions {
  std::string input;      ///< drive folder (.../2011_09_26_drive_0001_sync) or a folder above it
  std::string calib_dir;  ///< folder of calib_*.txt; empty: the drive folder's parent
  std::string out_dir;    ///< output dataset folder (must not exist or be empty)
  std::string name;       ///< dataset name; empty: the drive folder's name
  std::string camera = "image_02";  ///< ground camera folder (image_00 .. image_03)
  /// Ground world: "gravity" (origin and heading of the first OXTS pose, z
  /// up, as the format requires) or "first-pose" (the devkit's: the first
  /// IMU frame, so the first pose is the identity but z is tilted).
  std::string world = "gravity";
  std::string pseudo_air;               ///< pseudo air agent name ([a-z0-9_]+); empty: none
  std::string air_camera = "image_03";  ///< the pseudo air agent's camera folder
  /// T_wa_wg of the pseudo air agent: x, y, z (m), yaw (deg).
  std::vector<double> air_offset = {0.0, 0.0, 0.0, 0.0};
  bool binary_pcd = true;  ///< binary (true) or ascii PCD scans

  template <class V>
  void VisitFields(V& v) {
    v("input", input);
    v("calib_dir", calib_dir);
    v("out_dir", out_dir);
    v("name", name);
    v("camera", camera);
    v("world", world);
    v("pseudo_air", pseudo_air);
    v("air_camera", air_camera);
    v("air_offset", air_offset);
    v("binary_pcd", binary_pcd);
  }
  void Check() const;
};

/// How many frames of one sensor timestamps.txt lists and how many have a
/// data file (only those are imported).
struct KittiSensorCount {
  std::string sensor;  ///< "image_02", "velodyne_points", "oxts", ...
  size_t listed = 0;
  size_t imported = 0;
  size_t Skipped() const { return listed - imported; }
};

struct KittiImportSummary {
  std::string drive_dir;
  std::string calib_dir;
  std::vector<KittiSensorCount> sensors;
  Pose T_wa_wg = Pose::Identity();  ///< of the pseudo air agent, when there is one
  /// Images and scans timed outside the OXTS poses (KITTI's first camera
  /// frame and scan come a few ms before the first OXTS packet): they are
  /// imported as they are; consumers interpolate odometry and skip them.
  size_t frames_outside_odometry = 0;
};

/// Finds the drive folder: `input` itself when it holds oxts/ and
/// velodyne_points/, else the one such folder up to two levels below.
/// Throws InputError(kMissingFile) when there is none or more than one.
std::string FindKittiDrive(const std::string& input);

/// "image_02" -> 2. Throws OptionError naming `field` for anything else
/// than image_00 .. image_03.
int KittiCameraIndex(const std::string& folder, const std::string& field);

/// Imports the drive into options.out_dir. Only frames whose data file
/// exists are imported (timestamps.txt may list more; the summary counts
/// them). Throws InputError naming file and line on bad input, OptionError
/// on bad options.
KittiImportSummary ImportKittiRaw(const KittiImportOptions& options);

}  // namespace ag
