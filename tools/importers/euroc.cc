#include "tools/importers/euroc.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>

#include "common/camera/camera.h"
#include "common/config/options.h"
#include "common/core/agent_name.h"
#include "common/core/error.h"
#include "tools/importers/dataset_edit.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

constexpr double kQuaternionTolerance = 1e-3;  // as ReadTum
constexpr double kRotationTolerance = 1e-6;    // T_BS holds ~12 significant digits

int64_t LineOf(const YAML::Node& node) { return node.Mark().line + 1; }

YAML::Node RequireKey(const YAML::Node& root, const std::string& path, const std::string& key) {
  const YAML::Node node = root[key];
  if (!node.IsDefined() || node.IsNull()) {
    throw InputError(InputErrorKind::kMissingField, path, 0, "no '" + key + "'");
  }
  return node;
}

std::string ReadText(const YAML::Node& node, const std::string& path, const std::string& key) {
  if (!node.IsScalar()) {
    throw InputError(InputErrorKind::kBadValue, path, LineOf(node),
                     "'" + key + "' must be a value");
  }
  return node.Scalar();
}

bool ParseDouble(const std::string& text, double* value) {
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  *value = std::strtod(text.c_str(), &end);
  return end == text.c_str() + text.size() && errno != ERANGE;
}

std::vector<double> ReadNumbers(const YAML::Node& node, const std::string& path,
                                const std::string& key, size_t expected) {
  if (!node.IsSequence()) {
    throw InputError(InputErrorKind::kBadValue, path, LineOf(node), "'" + key + "' must be a list");
  }
  if (node.size() != expected) {
    throw InputError(InputErrorKind::kMalformedRow, path, LineOf(node),
                     "'" + key + "' has " + std::to_string(node.size()) + " values, expected " +
                         std::to_string(expected));
  }
  std::vector<double> values;
  for (const YAML::Node& item : node) {
    double v = 0;
    if (!item.IsScalar() || !ParseDouble(item.Scalar(), &v)) {
      throw InputError(InputErrorKind::kMalformedRow, path, LineOf(item),
                       "'" + key + "' holds something that is not a number");
    }
    if (!std::isfinite(v)) {
      throw InputError(InputErrorKind::kNonFinite, path, LineOf(item), "'" + key + "'");
    }
    values.push_back(v);
  }
  return values;
}

std::string Trim(const std::string& text) {
  const size_t b = text.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const size_t e = text.find_last_not_of(" \t\r");
  return text.substr(b, e - b + 1);
}

bool ParseInt64(const std::string& text, int64_t* value) {
  if (text.empty() ||
      !std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return false;
  }
  errno = 0;
  *value = std::strtoll(text.c_str(), nullptr, 10);
  return errno != ERANGE;
}

size_t CountOutside(const std::vector<SensorFrame>& frames, const std::vector<StampedPose>& poses) {
  if (poses.empty()) return frames.size();
  return static_cast<size_t>(std::count_if(frames.begin(), frames.end(), [&](const SensorFrame& f) {
    return f.t_ns < poses.front().t_ns || f.t_ns > poses.back().t_ns;
  }));
}

}  // namespace

AgentCalibration ReadEurocCamera(const std::string& sensor_yaml) {
  const YAML::Node root = LoadYamlFile(sensor_yaml);
  if (!root.IsMap()) {
    throw InputError(InputErrorKind::kBadValue, sensor_yaml, 0, "not a YAML map");
  }
  AgentCalibration calibration;
  CameraParams& camera = calibration.camera.camera;

  const YAML::Node T_BS = RequireKey(root, sensor_yaml, "T_BS");
  const YAML::Node data = RequireKey(T_BS, sensor_yaml, "data");
  const std::vector<double> m = ReadNumbers(data, sensor_yaml, "T_BS.data", 16);
  const Eigen::Matrix4d M =
      Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(m.data());
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if (!IsRotation(R, kRotationTolerance) ||
      (M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    throw InputError(
        InputErrorKind::kNotRotation, sensor_yaml, LineOf(data),
        "T_BS is not a rigid transform (rotation orthonormal to 1e-6, last row 0 0 0 1)");
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  calibration.camera.T_body_camera.linear() = svd.matrixU() * svd.matrixV().transpose();
  calibration.camera.T_body_camera.translation() = M.block<3, 1>(0, 3);

  const std::vector<double> resolution =
      ReadNumbers(RequireKey(root, sensor_yaml, "resolution"), sensor_yaml, "resolution", 2);
  if (resolution[0] != std::round(resolution[0]) || resolution[1] != std::round(resolution[1]) ||
      resolution[0] <= 0 || resolution[1] <= 0 || resolution[0] > 1e6 || resolution[1] > 1e6) {
    throw InputError(InputErrorKind::kBadValue, sensor_yaml, LineOf(root["resolution"]),
                     "resolution must be two positive whole numbers [width, height]");
  }
  camera.width = static_cast<int>(resolution[0]);
  camera.height = static_cast<int>(resolution[1]);

  const YAML::Node model_node = RequireKey(root, sensor_yaml, "camera_model");
  const std::string model = ReadText(model_node, sensor_yaml, "camera_model");
  if (model != "pinhole") {
    throw InputError(InputErrorKind::kBadValue, sensor_yaml, LineOf(model_node),
                     "camera_model '" + model + "' is not supported (pinhole)");
  }
  const std::vector<double> k =
      ReadNumbers(RequireKey(root, sensor_yaml, "intrinsics"), sensor_yaml, "intrinsics", 4);
  camera.fx = k[0];
  camera.fy = k[1];
  camera.cx = k[2];
  camera.cy = k[3];

  const YAML::Node distortion_node = RequireKey(root, sensor_yaml, "distortion_model");
  const std::string distortion = ReadText(distortion_node, sensor_yaml, "distortion_model");
  const YAML::Node coefficients = RequireKey(root, sensor_yaml, "distortion_coefficients");
  if (distortion == "radial-tangential" || distortion == "radtan") {
    camera.model = "pinhole";
    const size_t n = coefficients.IsSequence() && coefficients.size() == 5 ? 5 : 4;
    camera.distortion = ReadNumbers(coefficients, sensor_yaml, "distortion_coefficients", n);
  } else if (distortion == "equidistant") {
    camera.model = "equidistant";
    camera.distortion = ReadNumbers(coefficients, sensor_yaml, "distortion_coefficients", 4);
  } else {
    throw InputError(InputErrorKind::kBadValue, sensor_yaml, LineOf(distortion_node),
                     "distortion_model '" + distortion +
                         "' is not supported (radial-tangential or equidistant)");
  }
  try {
    Camera validated(camera);
  } catch (const OptionError& e) {
    throw InputError(InputErrorKind::kBadValue, sensor_yaml, 0, e.what());
  }
  return calibration;
}

std::vector<StampedPose> ReadEurocGroundTruth(const std::string& csv_path) {
  std::ifstream in(csv_path, std::ios::binary);
  if (!in) throw InputError(InputErrorKind::kMissingFile, csv_path, 0, "cannot open");
  std::vector<StampedPose> poses;
  std::string text;
  int64_t line = 0;
  while (std::getline(in, text)) {
    ++line;
    const std::string row = Trim(text);
    if (row.empty() || row[0] == '#') continue;
    std::vector<std::string> fields;
    size_t begin = 0;
    while (true) {
      const size_t comma = row.find(',', begin);
      fields.push_back(Trim(row.substr(begin, comma - begin)));
      if (comma == std::string::npos) break;
      begin = comma + 1;
    }
    if (fields.size() < 8) {
      throw InputError(InputErrorKind::kMalformedRow, csv_path, line,
                       "expected at least 8 fields (timestamp, p_RS_R xyz, q_RS wxyz), got " +
                           std::to_string(fields.size()));
    }
    StampedPose pose;
    if (!ParseInt64(fields[0], &pose.t_ns)) {
      throw InputError(InputErrorKind::kMalformedRow, csv_path, line,
                       "timestamp '" + fields[0] + "' is not an integer number of nanoseconds");
    }
    double v[7];
    for (int i = 0; i < 7; ++i) {
      if (!ParseDouble(fields[i + 1], &v[i])) {
        throw InputError(
            InputErrorKind::kMalformedRow, csv_path, line,
            "field " + std::to_string(i + 2) + " '" + fields[i + 1] + "' is not a number");
      }
      if (!std::isfinite(v[i])) {
        throw InputError(InputErrorKind::kNonFinite, csv_path, line,
                         "field " + std::to_string(i + 2) + " '" + fields[i + 1] + "'");
      }
    }
    Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);  // w first
    if (std::abs(q.norm() - 1.0) > kQuaternionTolerance) {
      throw InputError(InputErrorKind::kNotRotation, csv_path, line,
                       "quaternion norm " + std::to_string(q.norm()) + " is not 1");
    }
    pose.T.linear() = q.normalized().toRotationMatrix();
    pose.T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    if (!poses.empty() && pose.t_ns <= poses.back().t_ns) {
      throw InputError(InputErrorKind::kUnsorted, csv_path, line,
                       "timestamp " + fields[0] + " is not after the previous one");
    }
    poses.push_back(pose);
  }
  if (poses.empty()) throw InputError(InputErrorKind::kMissingField, csv_path, 0, "no poses");
  return poses;
}

std::string FindEurocMav(const std::string& input) {
  std::error_code ec;
  for (const fs::path& candidate : {fs::path(input), fs::path(input) / "mav0"}) {
    if (fs::is_directory(candidate / "cam0", ec) &&
        fs::is_directory(candidate / "state_groundtruth_estimate0", ec)) {
      return candidate.string();
    }
  }
  throw InputError(InputErrorKind::kMissingFile, input, 0,
                   "not a EuRoC sequence in ASL layout (no mav0/cam0 and "
                   "mav0/state_groundtruth_estimate0 here)");
}

std::vector<StampedPose> AddRandomWalkDrift(const std::vector<StampedPose>& poses,
                                            double sigma_m_per_sqrt_s,
                                            double sigma_yaw_rad_per_sqrt_s, uint64_t seed) {
  if (sigma_m_per_sqrt_s == 0.0 && sigma_yaw_rad_per_sqrt_s == 0.0) return poses;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector4d drift = Eigen::Vector4d::Zero();  // x, y, z, yaw
  std::vector<StampedPose> out = poses;
  for (size_t i = 1; i < out.size(); ++i) {
    const double sqrt_dt = std::sqrt(1e-9 * static_cast<double>(poses[i].t_ns - poses[i - 1].t_ns));
    for (int k = 0; k < 3; ++k) drift[k] += sigma_m_per_sqrt_s * sqrt_dt * normal(rng);
    drift[3] += sigma_yaw_rad_per_sqrt_s * sqrt_dt * normal(rng);
    out[i].T = MakePose4Dof(drift[0], drift[1], drift[2], drift[3]) * poses[i].T;
  }
  return out;
}

void EurocImportOptions::Check() const {
  CheckOption(!input.empty(), "input", "is required (the EuRoC sequence folder)");
  CheckOption(IsValidAgentName(agent) && agent != "ground", "agent",
              "must be [a-z0-9_]+ and not 'ground', got '" + agent + "'");
  CheckOption(into.empty() != out_dir.empty(), "into",
              "give either into (an existing dataset) or out_dir (a new one)");
  CheckOption(out_dir.empty() || !ground_from.empty(), "ground_from",
              "is required with out_dir: a dataset needs exactly one ground agent, which EuRoC "
              "does not have; copy it from another dataset (or use into)");
  CheckOption(into.empty() || ground_from.empty(), "ground_from",
              "goes with out_dir, not with into (the dataset has its ground agent)");
  CheckOption(air_offset.empty() || air_offset.size() == 4, "air_offset",
              "must be 4 numbers: x, y, z (m), yaw (deg)");
  for (double v : air_offset) CheckOption(std::isfinite(v), "air_offset", "must be finite");
  CheckOption(drift_m_per_sqrt_s >= 0 && std::isfinite(drift_m_per_sqrt_s), "drift_m_per_sqrt_s",
              "must be >= 0");
  CheckOption(drift_yaw_deg_per_sqrt_s >= 0 && std::isfinite(drift_yaw_deg_per_sqrt_s),
              "drift_yaw_deg_per_sqrt_s", "must be >= 0");
}

EurocImportSummary ImportEuroc(const EurocImportOptions& options) {
  options.Check();
  const fs::path mav(FindEurocMav(options.input));
  const fs::path camera_dir = mav / options.camera;
  AirAgentContent content;
  content.calibration = ReadEurocCamera((camera_dir / "sensor.yaml").string());
  content.images =
      ReadFrameList((camera_dir / "data.csv").string(), (camera_dir / "data").string());
  content.groundtruth =
      ReadEurocGroundTruth((mav / "state_groundtruth_estimate0" / "data.csv").string());
  content.odometry = AddRandomWalkDrift(content.groundtruth, options.drift_m_per_sqrt_s,
                                        options.drift_yaw_deg_per_sqrt_s * M_PI / 180.0,
                                        static_cast<uint64_t>(options.seed));

  EurocImportSummary summary;
  summary.agent = options.agent;
  summary.images = content.images.size();
  summary.poses = content.groundtruth.size();
  summary.images_outside_groundtruth = CountOutside(content.images, content.groundtruth);
  summary.dataset_dir = options.into;
  if (!options.out_dir.empty()) {
    fs::path sequence = fs::absolute(mav).lexically_normal();
    if (sequence.filename().empty()) sequence = sequence.parent_path();
    if (sequence.filename() == "mav0") sequence = sequence.parent_path();
    const std::string name = options.name.empty() ? sequence.filename().string() : options.name;
    CopyGroundAgent(options.ground_from, options.out_dir, name,
                    "EuRoC MAV " + sequence.filename().string() + " (" + options.camera +
                        ") as air agent '" + options.agent +
                        "', imported by tools/import_euroc; ground agent copied from " +
                        options.ground_from);
    summary.dataset_dir = options.out_dir;
  }
  std::optional<Pose> T_wa_wg;
  if (!options.air_offset.empty()) {
    const std::vector<double>& o = options.air_offset;
    T_wa_wg = MakePose4Dof(o[0], o[1], o[2], o[3] * M_PI / 180.0);
  }
  try {
    AddAirAgent(summary.dataset_dir, options.agent, content, T_wa_wg);
  } catch (...) {
    // A new dataset without its air agent is not what was asked for.
    std::error_code ec;
    if (!options.out_dir.empty()) fs::remove_all(options.out_dir, ec);
    throw;
  }
  return summary;
}

}  // namespace ag
