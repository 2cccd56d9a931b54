#include "tools/importers/kitti_import.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "common/core/agent_name.h"
#include "common/dataset/dataset.h"
#include "common/pcd/pcd_io.h"
#include "tools/importers/kitti_raw.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

bool IsDir(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

bool IsDrive(const fs::path& path) {
  return IsDir(path / "oxts") && IsDir(path / "velodyne_points");
}

// KITTI names data files by frame index: 0000000042.png.
std::string FrameFileName(size_t index, const std::string& ext) {
  char name[32];
  std::snprintf(name, sizeof(name), "%010zu", index);
  return name + ext;
}

/// The frames of one sensor folder whose data file exists.
struct SensorFrames {
  std::vector<int64_t> t_ns;
  std::vector<std::string> paths;
  KittiSensorCount count;
};

SensorFrames ListFrames(const fs::path& drive, const std::string& sensor, const std::string& ext) {
  const fs::path dir = drive / sensor;
  const fs::path data = dir / "data";
  if (!IsDir(data)) {
    throw InputError(InputErrorKind::kMissingFile, data.string(), 0,
                     "folder does not exist (is '" + sensor + "' a sensor of this drive?)");
  }
  const std::vector<int64_t> stamps = ReadKittiTimestamps((dir / "timestamps.txt").string());
  SensorFrames frames;
  frames.count.sensor = sensor;
  frames.count.listed = stamps.size();
  for (size_t i = 0; i < stamps.size(); ++i) {
    const fs::path file = data / FrameFileName(i, ext);
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) continue;
    frames.t_ns.push_back(stamps[i]);
    frames.paths.push_back(file.string());
  }
  frames.count.imported = frames.t_ns.size();
  // A data file without a timestamp is a broken drive, not a missing frame.
  for (const fs::directory_entry& entry : fs::directory_iterator(data)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() != ext) continue;
    const std::string stem = entry.path().stem().string();
    const bool numeric = !stem.empty() && std::all_of(stem.begin(), stem.end(),
                                                      [](char c) { return c >= '0' && c <= '9'; });
    if (!numeric || stem.size() != 10 || std::stoull(stem) >= stamps.size()) {
      throw InputError(InputErrorKind::kBadValue, entry.path().string(), 0,
                       "no line of " + (dir / "timestamps.txt").string() + " (" +
                           std::to_string(stamps.size()) + " lines) times this file");
    }
  }
  if (frames.t_ns.empty()) {
    throw InputError(InputErrorKind::kMissingFile, data.string(), 0,
                     "none of the " + std::to_string(stamps.size()) + " frames listed in " +
                         (dir / "timestamps.txt").string() + " has a " + ext + " file");
  }
  return frames;
}

void CopyImages(DatasetWriter* writer, const std::string& agent, const SensorFrames& frames) {
  for (size_t i = 0; i < frames.t_ns.size(); ++i) {
    const std::string target = writer->AddImage(agent, frames.t_ns[i], ".png");
    std::error_code ec;
    fs::copy_file(frames.paths[i], target, fs::copy_options::overwrite_existing, ec);
    if (ec) {
      throw InputError(InputErrorKind::kMissingFile, target, 0,
                       "cannot copy " + frames.paths[i] + ": " + ec.message());
    }
  }
}

size_t CountOutside(const std::vector<int64_t>& t_ns, const std::vector<StampedPose>& poses) {
  return static_cast<size_t>(std::count_if(t_ns.begin(), t_ns.end(), [&](int64_t t) {
    return t < poses.front().t_ns || t > poses.back().t_ns;
  }));
}

}  // namespace

void KittiImportOptions::Check() const {
  CheckOption(!input.empty(), "input", "is required (the KITTI drive folder)");
  CheckOption(!out_dir.empty(), "out_dir", "is required");
  KittiCameraIndex(camera, "camera");
  CheckOption(world == "gravity" || world == "first-pose", "world",
              "must be 'gravity' or 'first-pose', got '" + world + "'");
  if (!pseudo_air.empty()) {
    CheckOption(IsValidAgentName(pseudo_air) && pseudo_air != "ground", "pseudo_air",
                "must be [a-z0-9_]+ and not 'ground', got '" + pseudo_air + "'");
    KittiCameraIndex(air_camera, "air_camera");
    CheckOption(air_camera != camera, "air_camera", "must differ from camera");
  }
  CheckOption(air_offset.size() == 4, "air_offset", "must be 4 numbers: x, y, z (m), yaw (deg)");
  for (double v : air_offset) CheckOption(std::isfinite(v), "air_offset", "must be finite");
}

int KittiCameraIndex(const std::string& folder, const std::string& field) {
  CheckOption(
      folder.size() == 8 && folder.rfind("image_0", 0) == 0 && folder[7] >= '0' && folder[7] <= '3',
      field, "must be image_00 .. image_03, got '" + folder + "'");
  return folder[7] - '0';
}

std::string FindKittiDrive(const std::string& input) {
  const fs::path root(input);
  if (!IsDir(root)) {
    throw InputError(InputErrorKind::kMissingFile, input, 0, "folder does not exist");
  }
  if (IsDrive(root)) return root.string();
  std::vector<fs::path> found;
  for (const fs::directory_entry& a : fs::directory_iterator(root)) {
    if (!IsDir(a.path())) continue;
    if (IsDrive(a.path())) found.push_back(a.path());
    for (const fs::directory_entry& b : fs::directory_iterator(a.path())) {
      if (IsDrive(b.path())) found.push_back(b.path());
    }
  }
  if (found.size() != 1) {
    throw InputError(InputErrorKind::kMissingFile, input, 0,
                     found.empty() ? "no KITTI drive folder (with oxts/ and velodyne_points/) "
                                     "here or up to two levels below"
                                   : std::to_string(found.size()) +
                                         " KITTI drive folders below; give one of them");
  }
  return found.front().string();
}

KittiImportSummary ImportKittiRaw(const KittiImportOptions& options) {
  options.Check();
  KittiImportSummary summary;
  const fs::path drive(FindKittiDrive(options.input));
  summary.drive_dir = drive.string();
  summary.calib_dir =
      options.calib_dir.empty() ? fs::absolute(drive).parent_path().string() : options.calib_dir;
  const KittiCalibration calibration = ReadKittiCalibration(summary.calib_dir);

  // Poses: one per OXTS packet that exists, body = the IMU.
  const SensorFrames oxts = ListFrames(drive, "oxts", ".txt");
  std::vector<OxtsPacket> packets;
  for (const std::string& path : oxts.paths) packets.push_back(ReadOxtsPacket(path));
  const std::vector<Pose> poses = OxtsToPoses(
      packets, options.world == "gravity" ? KittiWorld::kGravityAligned : KittiWorld::kFirstPose);
  std::vector<StampedPose> T_wg_body(poses.size());
  for (size_t i = 0; i < poses.size(); ++i) T_wg_body[i] = {oxts.t_ns[i], poses[i]};

  const SensorFrames images = ListFrames(drive, options.camera, ".png");
  const SensorFrames velodyne = ListFrames(drive, "velodyne_points", ".bin");
  summary.sensors = {images.count, velodyne.count, oxts.count};
  summary.frames_outside_odometry =
      CountOutside(images.t_ns, T_wg_body) + CountOutside(velodyne.t_ns, T_wg_body);
  // Every input is listed before the output folder is created.
  SensorFrames air_images;
  if (!options.pseudo_air.empty()) {
    air_images = ListFrames(drive, options.air_camera, ".png");
    summary.sensors.push_back(air_images.count);
    summary.frames_outside_odometry += CountOutside(air_images.t_ns, T_wg_body);
  }

  const std::string drive_name = drive.filename().string();
  const std::string description =
      "KITTI raw " + drive_name + " imported by tools/import_kitti: ground = " + options.camera +
      " + Velodyne HDL-64 + OXTS poses (body = IMU, world '" + options.world +
      "'; groundtruth.tum = odometry.tum = OXTS)" +
      (options.pseudo_air.empty()
           ? std::string()
           : "; pseudo air agent '" + options.pseudo_air + "' = " + options.air_camera +
                 " in a world moved by the T_wa_wg of groundtruth.yaml") +
      ". License: CC BY-NC-SA 3.0 (KITTI).";
  DatasetWriter writer(options.out_dir, options.name.empty() ? drive_name : options.name,
                       description);
  writer.BeginGround(
      KittiAgentCalibration(calibration, KittiCameraIndex(options.camera, "camera"), true));
  CopyImages(&writer, "ground", images);
  for (size_t i = 0; i < velodyne.t_ns.size(); ++i) {
    // Written as recorded: see "Velodyne scans" in tools/importers/README.md.
    WriteScan(writer.AddScan(velodyne.t_ns[i]), ReadKittiVelodyne(velodyne.paths[i]),
              options.binary_pcd);
  }
  writer.SetOdometry("ground", T_wg_body);
  writer.SetGroundTruthTrajectory("ground", T_wg_body);

  if (!options.pseudo_air.empty()) {
    const std::vector<double>& o = options.air_offset;
    summary.T_wa_wg = MakePose4Dof(o[0], o[1], o[2], o[3] * M_PI / 180.0);
    writer.BeginAir(
        options.pseudo_air,
        KittiAgentCalibration(calibration, KittiCameraIndex(options.air_camera, "air_camera"),
                              /*with_lidar=*/false));
    CopyImages(&writer, options.pseudo_air, air_images);
    std::vector<StampedPose> T_wa_body = T_wg_body;
    for (StampedPose& p : T_wa_body) p.T = summary.T_wa_wg * p.T;
    writer.SetOdometry(options.pseudo_air, T_wa_body);
    writer.SetGroundTruthTrajectory(options.pseudo_air, T_wa_body);
    DatasetGroundTruth truth;
    truth.T_wa_wg[options.pseudo_air] = summary.T_wa_wg;
    writer.SetGroundTruth(truth);
  }
  writer.Finish();
  return summary;
}

}  // namespace ag
