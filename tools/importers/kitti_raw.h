#pragma once

// Readers of the KITTI raw dataset (Geiger et al., "Vision meets Robotics:
// The KITTI Dataset", IJRR 2013, and its raw-data devkit): timestamps.txt,
// the three calibration files and OXTS packets, and the conversions the
// importer needs (OXTS to poses, calibration to T_body_camera and
// T_body_lidar with body = the IMU/OXTS frame). Every error is an
// ag::InputError naming file, line and problem.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "common/dataset/dataset.h"
#include "common/geometry/pose.h"
#include "common/pcd/pcd_io.h"

namespace ag {

/// Parses a KITTI timestamp "YYYY-MM-DD hh:mm:ss.fffffffff" exactly (integer
/// arithmetic, no double) into nanoseconds since 1970-01-01 00:00:00, taking
/// the time as UTC (KITTI does not say which zone; only differences matter).
/// 1 to 9 decimals, or none. Returns false on bad syntax or an impossible
/// date or time.
bool ParseKittiTimestampNs(const std::string& text, int64_t* t_ns);

/// Reads a timestamps.txt (one timestamp per line; a final empty line is
/// allowed). Throws InputError naming file and line on a bad line or a time
/// not strictly after the previous one.
std::vector<int64_t> ReadKittiTimestamps(const std::string& path);

/// The raw-data calibration of one recording day (calib_cam_to_cam.txt,
/// calib_velo_to_cam.txt, calib_imu_to_velo.txt).
struct KittiCalibration {
  /// Rectified projection matrices of cameras 0-3 (P_rect_0x, 3x4): they map
  /// points in the rectified camera-0 frame to pixels of rectified camera x.
  std::array<Eigen::Matrix<double, 3, 4>, 4> P_rect;
  /// Rectified image size of cameras 0-3 (S_rect_0x: width, height in px).
  std::array<Eigen::Vector2i, 4> image_size;
  /// R_rect_00 as a transform: unrectified camera 0 -> rectified camera 0.
  Pose T_rect0_cam0 = Pose::Identity();
  Pose T_cam0_velo = Pose::Identity();  ///< calib_velo_to_cam.txt R, T
  Pose T_velo_imu = Pose::Identity();   ///< calib_imu_to_velo.txt R, T
};

/// Reads the three calibration files from `calib_dir` (the date folder,
/// e.g. .../2011_09_26). Rotations must be orthonormal to 1e-5 (the files
/// hold 7 significant digits) and are replaced by the nearest rotation.
KittiCalibration ReadKittiCalibration(const std::string& calib_dir);

/// T_rect0_camx: the rectified camera `index` (0-3) relative to rectified
/// camera 0. Rectified cameras share R_rect_00's orientation; P_rect_0x =
/// K [I | t] with t = K^-1 P_rect_0x(:, 3) (mostly the baseline along x,
/// P(0,3) / fx: -0.06 m for camera 2, +0.47 m for camera 3), so the camera
/// centre sits at -t in rectified camera-0 coordinates.
Pose KittiRectifiedCameraInCam0(const KittiCalibration& calibration, int index);

/// The nominal calibration of the ground agent in the dataset format for
/// rectified camera `camera_index` (2 or 3 for colour): pinhole with the
/// rectified intrinsics from P_rect (no distortion: images are rectified),
/// T_body_camera and T_body_lidar with body = the IMU/OXTS frame.
/// `with_lidar` adds the Velodyne (ground agent); without it the result
/// suits an air agent.
AgentCalibration KittiAgentCalibration(const KittiCalibration& calibration, int camera_index,
                                       bool with_lidar);

/// The first six values of one OXTS packet (oxts/dataformat.txt).
struct OxtsPacket {
  double lat_deg = 0;  ///< latitude (deg)
  double lon_deg = 0;  ///< longitude (deg)
  double alt_m = 0;    ///< altitude (m)
  double roll = 0;     ///< rad, 0 = level, positive = left side up
  double pitch = 0;    ///< rad, 0 = level, positive = front down
  double yaw = 0;      ///< rad, 0 = east, positive counter-clockwise
};

/// Reads one oxts/data/*.txt file (one line of 30 numbers; the first six are
/// kept). Throws InputError naming file and line.
OxtsPacket ReadOxtsPacket(const std::string& path);

/// Reads one velodyne_points/data/*.bin scan (float32 x y z reflectance per
/// point, little-endian, LiDAR frame) with reflectance as intensity. Throws
/// InputError naming the file: kMissingFile, kMalformedRow (size not a
/// multiple of 16 bytes), kNonFinite (naming the point index).
PointCloud ReadKittiVelodyne(const std::string& path);

/// Mercator scale of the devkit (latToScale.m): cos(lat).
double KittiLatToScale(double lat_deg);

/// Devkit latlonToMercator.m: (x east, y north) in metres for an Earth
/// radius of 6378137 m, scaled by `scale` (KittiLatToScale of the first
/// frame).
Eigen::Vector2d KittiLatLonToMercator(double lat_deg, double lon_deg, double scale);

/// Devkit convertOxtsToPose.m without its first-pose normalisation:
/// T_enu_imu with translation (Mercator x, y, altitude) and rotation
/// Rz(yaw) Ry(pitch) Rx(roll). The IMU frame is x forward, y left, z up.
Pose OxtsToEnuPose(const OxtsPacket& packet, double scale);

/// How the ground world wg is placed relative to the first OXTS pose.
enum class KittiWorld {
  /// Origin at the first IMU position, x along its heading, z up (removes
  /// the first pose's translation and yaw only): gravity-aligned as the
  /// dataset format requires. The first pose keeps its roll and pitch.
  kGravityAligned,
  /// The devkit's convention: wg = the first IMU frame (the first pose is
  /// exactly the identity). Tilted from gravity by the first roll/pitch.
  kFirstPose,
};

/// T_wg_imu for every packet (devkit convertOxtsToPose.m with the Mercator
/// scale of the first packet), expressed in the world `world` chooses.
std::vector<Pose> OxtsToPoses(const std::vector<OxtsPacket>& packets, KittiWorld world);

}  // namespace ag
