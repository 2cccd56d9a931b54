// tools/import_kitti: a KITTI raw drive (synced + rectified) -> dataset v1.
//
//   tools/import_kitti .../2011_09_26/2011_09_26_drive_0001_sync --out /tmp/kitti
//   tools/import_kitti .../2011_09_26_drive_0001_sync --out /tmp/kitti_air --pseudo-air kitti_air
//       --air-camera image_03 --air-offset 5,-3,2,30

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <exception>

#include "common/core/error.h"
#include "common/logging/logging.h"
#include "tools/importers/kitti_import.h"

int main(int argc, char** argv) {
  CLI::App app{
      "Imports a KITTI raw drive (synced + rectified) into the air-ground dataset format "
      "(../shared/spec/dataset.md)"};
  ag::KittiImportOptions options;
  std::string log_level = "info";
  app.add_option("drive", options.input,
                 "drive folder (.../2011_09_26_drive_0001_sync) or a folder up to two levels "
                 "above it")
      ->required();
  app.add_option("--out", options.out_dir, "output dataset folder (must not exist or be empty)")
      ->required();
  app.add_option("--calib-dir", options.calib_dir,
                 "folder of calib_cam_to_cam.txt etc. (default: the drive folder's parent)");
  app.add_option("--name", options.name, "dataset name (default: the drive folder's name)");
  app.add_option("--camera", options.camera, "ground camera: image_02 (default) .. image_03");
  app.add_option("--world", options.world,
                 "ground world: 'gravity' (default; first OXTS position and heading, z up) or "
                 "'first-pose' (the devkit's: the first IMU frame)");
  app.add_option("--pseudo-air", options.pseudo_air,
                 "add a pseudo air agent of this name from --air-camera");
  app.add_option("--air-camera", options.air_camera, "the pseudo air agent's camera (image_03)");
  app.add_option("--air-offset", options.air_offset,
                 "T_wa_wg of the pseudo air agent: x,y,z (m),yaw (deg), e.g. -5,2,0,30")
      ->delimiter(',')
      ->expected(4);
  app.add_flag(
      "--ascii-pcd", [&](int64_t) { options.binary_pcd = false; },
      "write ascii instead of binary PCD scans");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  ag::LoggingOptions logging;
  logging.level = log_level;
  ag::SetupLogging("import_kitti", logging);
  try {
    const ag::KittiImportSummary summary = ag::ImportKittiRaw(options);
    spdlog::info("import_kitti: drive {} (calibration from {})", summary.drive_dir,
                 summary.calib_dir);
    for (const ag::KittiSensorCount& s : summary.sensors) {
      spdlog::info("import_kitti: {:<16} {} of {} frames imported, {} skipped (no data file)",
                   s.sensor, s.imported, s.listed, s.Skipped());
    }
    if (summary.frames_outside_odometry > 0) {
      spdlog::warn(
          "import_kitti: {} image(s)/scan(s) are timed outside the OXTS poses (imported as they "
          "are; odometry cannot be interpolated there)",
          summary.frames_outside_odometry);
    }
    if (!options.pseudo_air.empty()) {
      const ag::Pose& T = summary.T_wa_wg;
      spdlog::info(
          "import_kitti: pseudo air agent '{}' from {}, T_wa_wg = x {:.3f} y {:.3f} z {:.3f} m, "
          "yaw {:.2f} deg (groundtruth.yaml)",
          options.pseudo_air, options.air_camera, T.translation().x(), T.translation().y(),
          T.translation().z(), ag::YawOf(T.linear()) * 180.0 / M_PI);
    }
    spdlog::info("import_kitti: wrote {}", options.out_dir);
  } catch (const ag::InputError& e) {
    spdlog::error("{}", e.what());
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("import_kitti failed: {}", e.what());
    return 1;
  }
  return 0;
}
