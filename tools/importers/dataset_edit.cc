#include "tools/importers/dataset_edit.h"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "common/core/agent_name.h"
#include "common/core/error.h"
#include "common/geometry/tum_io.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

void CopyFile(const std::string& from, const std::string& to) {
  std::error_code ec;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, ec);
  if (ec) {
    throw InputError(InputErrorKind::kMissingFile, to, 0,
                     "cannot copy " + from + ": " + ec.message());
  }
}

void CheckSorted(const std::vector<StampedPose>& poses, const std::string& tum_path) {
  for (size_t i = 1; i < poses.size(); ++i) {
    if (poses[i].t_ns <= poses[i - 1].t_ns) {
      throw InputError(
          InputErrorKind::kUnsorted, tum_path, static_cast<int64_t>(i) + 2,
          "pose at " + FormatDecimalSecondsNs(poses[i].t_ns) + " s is not after the previous one");
    }
  }
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
  if (!out) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot write");
}

// Writes the whole agent folder at `dir` (which must not exist).
void WriteAirFolder(const std::string& dir, const std::string& final_dir,
                    const AirAgentContent& content) {
  std::error_code ec;
  fs::create_directories(dir + "/images", ec);
  if (ec) throw InputError(InputErrorKind::kMissingFile, dir, 0, "cannot create: " + ec.message());
  // Messages name the final paths: that is where the user will look.
  std::string csv = "#timestamp [ns],filename\n";
  for (size_t i = 0; i < content.images.size(); ++i) {
    const SensorFrame& frame = content.images[i];
    if (i > 0 && frame.t_ns <= content.images[i - 1].t_ns) {
      throw InputError(
          InputErrorKind::kUnsorted, final_dir + "/images.csv", static_cast<int64_t>(i) + 2,
          "image at " + std::to_string(frame.t_ns) + " ns is not after the previous one");
    }
    const std::string name = std::to_string(frame.t_ns) + fs::path(frame.path).extension().string();
    CopyFile(frame.path, dir + "/images/" + name);
    csv += std::to_string(frame.t_ns) + "," + name + "\n";
  }
  CheckSorted(content.odometry, final_dir + "/odometry.tum");
  CheckSorted(content.groundtruth, final_dir + "/groundtruth.tum");
  WriteBytes(dir + "/images.csv", csv);
  WriteCalibration(dir + "/calibration.yaml", content.calibration);
  WriteTum(dir + "/odometry.tum", content.odometry, "T_wa_body: timestamp tx ty tz qx qy qz qw");
  if (!content.groundtruth.empty()) {
    WriteTum(dir + "/groundtruth.tum", content.groundtruth,
             "true T_wa_body: timestamp tx ty tz qx qy qz qw");
  }
}

}  // namespace

void CopyGroundAgent(const std::string& source_dir, const std::string& out_dir,
                     const std::string& name, const std::string& description) {
  const Dataset source = ReadDataset(source_dir);
  DatasetWriter writer(out_dir, name, description);
  writer.BeginGround(source.ground.calibration);
  for (const SensorFrame& image : source.ground.images) {
    CopyFile(image.path,
             writer.AddImage("ground", image.t_ns, fs::path(image.filename).extension().string()));
  }
  for (const SensorFrame& scan : source.ground.scans) {
    CopyFile(scan.path, writer.AddScan(scan.t_ns));
  }
  writer.SetOdometry("ground", source.ground.odometry);
  writer.SetGroundTruthTrajectory("ground", source.ground.groundtruth);
  writer.Finish();
}

void AddAirAgent(const std::string& dataset_dir, const std::string& agent,
                 const AirAgentContent& content, const std::optional<Pose>& T_wa_wg) {
  if (!IsValidAgentName(agent) || agent == "ground") {
    throw std::invalid_argument("air agent name '" + agent +
                                "' must be [a-z0-9_]+ and not 'ground'");
  }
  const Dataset before = ReadDataset(dataset_dir);
  const std::string final_dir = AgentDir(dataset_dir, agent);
  std::error_code ec;
  if (before.air.count(agent) || fs::exists(final_dir, ec)) {
    throw std::invalid_argument("the dataset " + dataset_dir + " already has an air agent '" +
                                agent + "' (choose another name)");
  }
  // Readers skip air/ entries starting with '.', so a half-written agent is
  // invisible until the rename.
  const std::string staging = dataset_dir + "/air/." + agent + ".partial";
  fs::remove_all(staging, ec);
  try {
    WriteAirFolder(staging, final_dir, content);
  } catch (...) {
    fs::remove_all(staging, ec);
    throw;
  }
  fs::rename(staging, final_dir);

  const std::string groundtruth_path = dataset_dir + "/groundtruth.yaml";
  const bool had_groundtruth = fs::is_regular_file(groundtruth_path, ec);
  const std::string old_groundtruth = had_groundtruth ? ReadBytes(groundtruth_path) : "";
  try {
    if (T_wa_wg) {
      DatasetGroundTruth truth = before.groundtruth.value_or(DatasetGroundTruth{});
      truth.T_wa_wg[agent] = *T_wa_wg;
      const std::string partial = dataset_dir + "/.groundtruth.yaml.partial";
      WriteGroundTruth(partial, truth);
      fs::rename(partial, groundtruth_path);
    }
    ReadDataset(dataset_dir);  // what was written must read back
  } catch (...) {
    fs::remove_all(final_dir, ec);
    if (had_groundtruth) {
      WriteBytes(groundtruth_path, old_groundtruth);
    } else {
      fs::remove(groundtruth_path, ec);
    }
    throw;
  }
}

}  // namespace ag
