// Writing a dataset (../shared/spec/dataset.md). Finish() validates
// everything before it writes anything, so a refused dataset leaves no
// half-written index files behind, and what it writes reads back with
// ReadDataset unchanged.

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <stdexcept>

#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/dataset/dataset.h"
#include "common/dataset/dataset_internal.h"
#include "common/dataset/yaml_io.h"
#include "common/geometry/tum_io.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

constexpr const char* kFrameListHeader = "#timestamp [ns],filename\n";

void MakeDirs(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(InputErrorKind::kMissingFile, dir, 0, "cannot create: " + ec.message());
}

// Line numbers below count the header line the writer puts first.
void CheckFrames(const std::vector<SensorFrame>& frames, const std::string& csv_path) {
  for (size_t i = 0; i < frames.size(); ++i) {
    const int64_t line = static_cast<int64_t>(i) + 2;
    if (i > 0 && frames[i].t_ns <= frames[i - 1].t_ns) {
      throw InputError(InputErrorKind::kUnsorted, csv_path, line,
                       "frame at " + std::to_string(frames[i].t_ns) +
                           " ns was added after the one at " + std::to_string(frames[i - 1].t_ns) +
                           " ns; frames must be strictly increasing in time");
    }
    std::error_code ec;
    if (!fs::is_regular_file(frames[i].path, ec)) {
      throw InputError(InputErrorKind::kMissingFile, csv_path, line,
                       "'" + frames[i].path + "' was added but never written");
    }
  }
}

void CheckPoses(const std::vector<StampedPose>& poses, const std::string& tum_path) {
  for (size_t i = 1; i < poses.size(); ++i) {
    if (poses[i].t_ns <= poses[i - 1].t_ns) {
      throw InputError(InputErrorKind::kUnsorted, tum_path, static_cast<int64_t>(i) + 2,
                       "pose at " + FormatDecimalSecondsNs(poses[i].t_ns) + " s follows one at " +
                           FormatDecimalSecondsNs(poses[i - 1].t_ns) +
                           " s; poses must be strictly increasing in time");
    }
  }
}

void WriteFrameList(const std::string& path, const std::vector<SensorFrame>& frames) {
  std::string text = kFrameListHeader;
  text.reserve(text.size() + frames.size() * 48);
  for (const SensorFrame& f : frames) text += std::to_string(f.t_ns) + "," + f.filename + "\n";
  internal::WriteTextFile(path, text);
}

}  // namespace

DatasetWriter::DatasetWriter(const std::string& dir, const std::string& name,
                             const std::string& description)
    : dir_(dir) {
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) {
      throw InputError(InputErrorKind::kBadValue, dir, 0, "exists and is not a folder");
    }
    if (!fs::is_empty(dir, ec)) {
      throw InputError(InputErrorKind::kBadValue, dir, 0,
                       "output folder exists and is not empty; refusing to mix datasets");
    }
  }
  MakeDirs(dir);
  internal::DatasetInfo info;
  info.format_version = internal::kFormatVersion;
  info.name = name;
  info.description = description;
  internal::WriteDatasetInfo(dir + "/dataset.yaml", info);
}

DatasetWriter::AgentState& DatasetWriter::Agent(const std::string& agent) {
  const auto it = agents_.find(agent);
  if (it == agents_.end()) {
    throw std::invalid_argument("DatasetWriter: unknown agent '" + agent +
                                "' (declare it with BeginGround / BeginAir first)");
  }
  return it->second;
}

void DatasetWriter::BeginGround(const AgentCalibration& calibration) {
  if (agents_.count("ground"))
    throw std::invalid_argument("DatasetWriter: ground agent declared twice");
  CheckOption(calibration.lidar.has_value(), "lidar", "the ground agent needs a lidar calibration");
  Camera validated(calibration.camera.camera);  // throws OptionError naming the field
  AgentState state;
  state.dir = AgentDir(dir_, "ground");
  state.calibration = calibration;
  MakeDirs(state.dir + "/images");
  MakeDirs(state.dir + "/scans");
  agents_["ground"] = std::move(state);
}

void DatasetWriter::BeginAir(const std::string& agent, const AgentCalibration& calibration) {
  if (!IsValidAgentName(agent) || agent == "ground") {
    throw std::invalid_argument("DatasetWriter: air agent name '" + agent +
                                "' must be [a-z0-9_]+ and not 'ground'");
  }
  if (agents_.count(agent)) {
    throw std::invalid_argument("DatasetWriter: air agent '" + agent + "' declared twice");
  }
  Camera validated(calibration.camera.camera);
  AgentState state;
  state.dir = AgentDir(dir_, agent);
  state.calibration = calibration;
  MakeDirs(state.dir + "/images");
  agents_[agent] = std::move(state);
}

std::string DatasetWriter::AddImage(const std::string& agent, int64_t t_ns,
                                    const std::string& ext) {
  std::string lower;
  for (char c : ext) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower != ".png" && lower != ".jpg" && lower != ".jpeg") {
    throw std::invalid_argument("DatasetWriter: image extension '" + ext +
                                "' is not .png, .jpg or .jpeg");
  }
  AgentState& state = Agent(agent);
  SensorFrame frame;
  frame.t_ns = t_ns;
  frame.filename = std::to_string(t_ns) + ext;
  frame.path = state.dir + "/images/" + frame.filename;
  state.images.push_back(frame);
  return frame.path;
}

std::string DatasetWriter::AddScan(int64_t t_ns) {
  AgentState& state = Agent("ground");
  SensorFrame frame;
  frame.t_ns = t_ns;
  frame.filename = std::to_string(t_ns) + ".pcd";
  frame.path = state.dir + "/scans/" + frame.filename;
  state.scans.push_back(frame);
  return frame.path;
}

void DatasetWriter::SetOdometry(const std::string& agent, const std::vector<StampedPose>& poses) {
  Agent(agent).odometry = poses;
}

void DatasetWriter::SetGroundTruthTrajectory(const std::string& agent,
                                             const std::vector<StampedPose>& poses) {
  Agent(agent).groundtruth = poses;
}

void DatasetWriter::SetGroundTruth(const DatasetGroundTruth& groundtruth) {
  groundtruth_ = groundtruth;
}

void DatasetWriter::Finish() {
  if (finished_) throw std::logic_error("DatasetWriter: Finish() called twice");
  if (!agents_.count("ground")) {
    throw std::logic_error("DatasetWriter: a dataset needs its ground agent (BeginGround)");
  }
  // Validate everything first: nothing is written unless all of it is right.
  for (const auto& [name, state] : agents_) {
    CheckFrames(state.images, state.dir + "/images.csv");
    CheckFrames(state.scans, state.dir + "/scans.csv");
    CheckPoses(state.odometry, state.dir + "/odometry.tum");
    CheckPoses(state.groundtruth, state.dir + "/groundtruth.tum");
  }
  if (groundtruth_) {
    auto check_agent = [&](const std::string& agent, const char* where) {
      if (agent == "ground" || !agents_.count(agent)) {
        throw std::invalid_argument(std::string("DatasetWriter: groundtruth ") + where +
                                    " names '" + agent + "', which is not an air agent");
      }
    };
    for (const auto& kv : groundtruth_->T_wa_wg) check_agent(kv.first, "T_wa_wg");
    for (const auto& kv : groundtruth_->air_true_camera) check_agent(kv.first, "true_calibration");
  }

  for (const auto& [name, state] : agents_) {
    WriteCalibration(state.dir + "/calibration.yaml", state.calibration);
    WriteFrameList(state.dir + "/images.csv", state.images);
    if (name == "ground") WriteFrameList(state.dir + "/scans.csv", state.scans);
    WriteTum(state.dir + "/odometry.tum", state.odometry);
    if (!state.groundtruth.empty()) WriteTum(state.dir + "/groundtruth.tum", state.groundtruth);
  }
  if (groundtruth_) WriteGroundTruth(dir_ + "/groundtruth.yaml", *groundtruth_);
  finished_ = true;
}

}  // namespace ag
