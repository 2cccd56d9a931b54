// Reading a dataset (../shared/spec/dataset.md): the folder layout, the
// EuRoC-style frame lists and, through ReadTum and the YAML readers, every
// other index file. Nothing is skipped silently: the first problem stops the
// read with an ag::InputError naming file, line and problem.

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "common/core/error.h"
#include "common/dataset/dataset.h"
#include "common/dataset/dataset_internal.h"
#include "common/geometry/tum_io.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

std::string Join(const std::string& dir, const std::string& name) {
  if (dir.empty()) return name;
  return dir.back() == '/' ? dir + name : dir + "/" + name;
}

bool IsFile(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

bool IsDir(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

std::string Trim(const std::string& text, size_t begin, size_t end) {
  while (begin < end && (text[begin] == ' ' || text[begin] == '\t')) ++begin;
  while (end > begin && (text[end - 1] == ' ' || text[end - 1] == '\t')) --end;
  return text.substr(begin, end - begin);
}

// Strict int64 ("-" allowed, digits only, no overflow).
bool ParseInt64(const std::string& text, int64_t* value) {
  if (text.empty()) return false;
  for (size_t i = 0; i < text.size(); ++i) {
    const bool digit = text[i] >= '0' && text[i] <= '9';
    if (!digit && !(i == 0 && text[i] == '-' && text.size() > 1)) return false;
  }
  errno = 0;
  const long long v = std::strtoll(text.c_str(), nullptr, 10);
  if (errno == ERANGE) return false;
  *value = v;
  return true;
}

AgentData ReadAgent(const std::string& dataset_dir, const std::string& name, bool is_ground) {
  AgentData agent;
  agent.name = name;
  agent.dir = AgentDir(dataset_dir, name);
  agent.calibration = ReadCalibration(Join(agent.dir, "calibration.yaml"), is_ground);
  agent.images = ReadFrameList(Join(agent.dir, "images.csv"), Join(agent.dir, "images"));
  if (is_ground)
    agent.scans = ReadFrameList(Join(agent.dir, "scans.csv"), Join(agent.dir, "scans"));
  agent.odometry = ReadTum(Join(agent.dir, "odometry.tum"));
  const std::string groundtruth = Join(agent.dir, "groundtruth.tum");
  if (IsFile(groundtruth)) agent.groundtruth = ReadTum(groundtruth);
  return agent;
}

}  // namespace

std::string AgentDir(const std::string& dataset_dir, const std::string& agent) {
  return agent == "ground" ? Join(dataset_dir, "ground") : Join(Join(dataset_dir, "air"), agent);
}

std::vector<SensorFrame> ReadFrameList(const std::string& csv_path, const std::string& data_dir) {
  if (!IsFile(csv_path)) {
    throw InputError(InputErrorKind::kMissingFile, csv_path, 0, "file does not exist");
  }
  if (!IsDir(data_dir)) {
    throw InputError(InputErrorKind::kMissingFile, data_dir, 0,
                     "folder does not exist (the files of " + csv_path + " live there)");
  }
  std::ifstream in(csv_path, std::ios::binary);
  if (!in) throw InputError(InputErrorKind::kMissingFile, csv_path, 0, "cannot open");
  std::vector<SensorFrame> frames;
  std::string line;
  int64_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    size_t end = line.size();
    if (end > 0 && line[end - 1] == '\r') --end;  // CRLF
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || first >= end || line[first] == '#') continue;
    const size_t comma = line.find(',', first);
    if (comma == std::string::npos || comma >= end) {
      throw InputError(InputErrorKind::kMalformedRow, csv_path, line_no,
                       "expected 2 fields 't_ns,filename', got 1");
    }
    const size_t second_comma = line.find(',', comma + 1);
    if (second_comma != std::string::npos && second_comma < end) {
      const auto fields = 1 + std::count(line.begin() + first, line.begin() + end, ',');
      throw InputError(InputErrorKind::kMalformedRow, csv_path, line_no,
                       "expected 2 fields 't_ns,filename', got " + std::to_string(fields));
    }
    SensorFrame frame;
    const std::string stamp = Trim(line, first, comma);
    if (!ParseInt64(stamp, &frame.t_ns)) {
      throw InputError(InputErrorKind::kMalformedRow, csv_path, line_no,
                       "timestamp '" + stamp + "' is not an integer number of nanoseconds");
    }
    frame.filename = Trim(line, comma + 1, end);
    if (frame.filename.empty()) {
      throw InputError(InputErrorKind::kMalformedRow, csv_path, line_no, "empty filename");
    }
    if (!frames.empty() && frame.t_ns <= frames.back().t_ns) {
      throw InputError(InputErrorKind::kUnsorted, csv_path, line_no,
                       "timestamp " + stamp + " is not after the previous one (" +
                           std::to_string(frames.back().t_ns) + ")");
    }
    frame.path = Join(data_dir, frame.filename);
    if (!IsFile(frame.path)) {
      throw InputError(InputErrorKind::kMissingFile, csv_path, line_no,
                       "'" + frame.filename + "' does not exist in " + data_dir);
    }
    frames.push_back(std::move(frame));
  }
  return frames;
}

Dataset ReadDataset(const std::string& dir) {
  if (!IsDir(dir)) {
    throw InputError(InputErrorKind::kMissingFile, dir, 0, "dataset folder does not exist");
  }
  Dataset dataset;
  dataset.dir = dir;
  const internal::DatasetInfo info = internal::ReadDatasetInfo(Join(dir, "dataset.yaml"));
  dataset.format_version = info.format_version;
  dataset.name = info.name;
  dataset.description = info.description;

  const std::string ground_dir = AgentDir(dir, "ground");
  if (!IsDir(ground_dir)) {
    throw InputError(InputErrorKind::kMissingFile, ground_dir, 0,
                     "folder does not exist (a dataset has exactly one ground agent)");
  }
  dataset.ground = ReadAgent(dir, "ground", /*is_ground=*/true);

  // air/ is optional (a dataset without air agents); its entries are not.
  const std::string air_dir = Join(dir, "air");
  std::vector<std::string> names;
  std::error_code ec;
  if (fs::exists(air_dir, ec)) {
    if (!IsDir(air_dir)) {
      throw InputError(InputErrorKind::kBadValue, air_dir, 0, "must be a folder of air agents");
    }
    for (const fs::directory_entry& entry : fs::directory_iterator(air_dir)) {
      const std::string name = entry.path().filename().string();
      if (!name.empty() && name[0] == '.') continue;  // .DS_Store, editor files
      if (!IsDir(entry.path().string())) {
        throw InputError(InputErrorKind::kBadValue, entry.path().string(), 0,
                         "air/ holds one folder per air agent; this is not a folder");
      }
      if (!IsValidAgentName(name)) {
        throw InputError(InputErrorKind::kBadValue, entry.path().string(), 0,
                         "air agent name '" + name + "' is not [a-z0-9_]+");
      }
      names.push_back(name);
    }
  }
  std::sort(names.begin(), names.end());
  for (const std::string& name : names) dataset.air[name] = ReadAgent(dir, name, false);

  const std::string groundtruth = Join(dir, "groundtruth.yaml");
  if (IsFile(groundtruth)) dataset.groundtruth = internal::ReadGroundTruthFor(groundtruth, &names);
  return dataset;
}

cv::Mat LoadImage(const SensorFrame& frame, int flags) {
  cv::Mat image = cv::imread(frame.path, flags);
  if (image.empty()) {
    throw InputError(InputErrorKind::kMissingFile, frame.path, 0,
                     "cannot read the image (missing, or not a PNG/JPEG file)");
  }
  if (image.depth() != CV_8U) {
    throw InputError(InputErrorKind::kBadValue, frame.path, 0,
                     "the dataset format needs 8-bit images");
  }
  return image;
}

}  // namespace ag
