// The three YAML files of a dataset: dataset.yaml, calibration.yaml and
// groundtruth.yaml (../shared/spec/dataset.md). Every map is closed: a key
// the format does not define is rejected, so a typo cannot silently leave a
// value at its default.

#include <algorithm>
#include <sstream>

#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/dataset/dataset.h"
#include "common/dataset/dataset_internal.h"
#include "common/dataset/yaml_io.h"

namespace ag {
namespace internal {
namespace {

int ReadImageSize(const YamlDoc& doc, const YAML::Node& camera, const char* key) {
  const YAML::Node node = Require(doc, camera, "camera", key);
  const int64_t value = ReadInt(doc, node, Dotted("camera", key));
  if (value <= 0 || value > (1 << 20)) {
    throw InputError(InputErrorKind::kBadValue, doc.path, LineOf(node),
                     "'camera." + std::string(key) + "' must be in [1, 1048576] px, got " +
                         std::to_string(value));
  }
  return static_cast<int>(value);
}

CameraParams ReadCameraParams(const YamlDoc& doc, const YAML::Node& camera) {
  CameraParams params;
  const YAML::Node model = Require(doc, camera, "camera", "model");
  params.model = ReadString(doc, model, "camera.model");
  params.width = ReadImageSize(doc, camera, "width");
  params.height = ReadImageSize(doc, camera, "height");
  const YAML::Node intrinsics = Require(doc, camera, "camera", "intrinsics");
  const std::vector<double> k = ReadDoubleList(doc, intrinsics, "camera.intrinsics", 4);
  params.fx = k[0];
  params.fy = k[1];
  params.cx = k[2];
  params.cy = k[3];
  const YAML::Node distortion = camera["distortion"];
  if (distortion.IsDefined() && !distortion.IsNull()) {
    params.distortion = ReadDoubleList(doc, distortion, "camera.distortion");
  }
  // Same validation as the estimator's ag::Camera, reported at the line of
  // the offending key.
  try {
    Camera validated(params);
  } catch (const OptionError& e) {
    const YAML::Node field = camera[e.field()];
    throw InputError(InputErrorKind::kBadValue, doc.path,
                     field.IsDefined() ? LineOf(field) : LineOf(camera),
                     "camera." + std::string(e.what()));
  }
  return params;
}

double ReadOptionalDouble(const YamlDoc& doc, const YAML::Node& map, const std::string& map_name,
                          const char* key, double fallback) {
  const YAML::Node node = map[key];
  if (!node.IsDefined()) return fallback;
  return ReadDouble(doc, node, Dotted(map_name, key));
}

void CheckAgentName(const YamlDoc& doc, const YAML::Node& key, const std::string& map_name,
                    const std::vector<std::string>* air_agents) {
  const std::string& name = key.Scalar();
  if (!IsValidAgentName(name)) {
    throw InputError(InputErrorKind::kBadValue, doc.path, LineOf(key),
                     "'" + Dotted(map_name, name) + "': agent names are [a-z0-9_]+");
  }
  if (air_agents && std::find(air_agents->begin(), air_agents->end(), name) == air_agents->end()) {
    throw InputError(InputErrorKind::kBadValue, doc.path, LineOf(key),
                     "'" + Dotted(map_name, name) + "': the dataset has no air agent '" + name +
                         "' (no folder air/" + name + ")");
  }
}

}  // namespace

DatasetInfo ReadDatasetInfo(const std::string& path) {
  const YamlDoc doc = LoadYaml(path);
  CheckMap(doc, doc.root, "", {"format_version", "name", "description"});
  DatasetInfo info;
  const YAML::Node version = Require(doc, doc.root, "", "format_version");
  const int64_t v = ReadInt(doc, version, "format_version");
  if (v != kFormatVersion) {
    throw InputError(InputErrorKind::kBadValue, path, LineOf(version),
                     "format_version " + std::to_string(v) +
                         " is not supported (this reader: " + std::to_string(kFormatVersion) + ")");
  }
  info.format_version = static_cast<int>(v);
  info.name = ReadString(doc, Require(doc, doc.root, "", "name"), "name");
  const YAML::Node description = doc.root["description"];
  if (description.IsDefined()) info.description = ReadString(doc, description, "description");
  return info;
}

void WriteDatasetInfo(const std::string& path, const DatasetInfo& info) {
  std::ostringstream out;
  out << "format_version: " << info.format_version << "\n"
      << "name: " << QuoteString(info.name) << "\n"
      << "description: " << QuoteString(info.description) << "\n";
  WriteTextFile(path, out.str());
}

DatasetGroundTruth ReadGroundTruthFor(const std::string& path,
                                      const std::vector<std::string>* air_agents) {
  const YamlDoc doc = LoadYaml(path);
  CheckMap(doc, doc.root, "", {"T_wa_wg", "true_calibration"});
  DatasetGroundTruth gt;
  const YAML::Node T_wa_wg = Require(doc, doc.root, "", "T_wa_wg");
  if (!T_wa_wg.IsNull()) {  // "T_wa_wg:" with no agent is an empty map
    if (!T_wa_wg.IsMap()) {
      throw InputError(InputErrorKind::kBadValue, path, LineOf(T_wa_wg),
                       "'T_wa_wg' must be a map from air agent name to a 4x4 matrix");
    }
    for (const auto& kv : T_wa_wg) {
      CheckAgentName(doc, kv.first, "T_wa_wg", air_agents);
      const std::string agent = kv.first.Scalar();
      if (gt.T_wa_wg.count(agent)) {
        throw InputError(InputErrorKind::kMalformedRow, path, LineOf(kv.first),
                         "duplicate key 'T_wa_wg." + agent + "'");
      }
      gt.T_wa_wg[agent] = ReadTransform(doc, kv.second, "T_wa_wg." + agent);
    }
  }

  const YAML::Node true_calibration = doc.root["true_calibration"];
  if (!true_calibration.IsDefined()) return gt;
  CheckMap(doc, true_calibration, "true_calibration", {"ground", "air"});
  const YAML::Node ground = true_calibration["ground"];
  if (ground.IsDefined()) {
    const std::string name = "true_calibration.ground";
    CheckMap(doc, ground, name, {"T_body_camera", "T_body_lidar", "camera_time_offset_s"});
    if (ground["T_body_camera"].IsDefined()) {
      CameraCalibration camera;
      camera.T_body_camera = ReadTransform(doc, ground["T_body_camera"], name + ".T_body_camera");
      camera.time_offset_s = ReadOptionalDouble(doc, ground, name, "camera_time_offset_s", 0.0);
      gt.ground_true_camera = camera;
    } else if (ground["camera_time_offset_s"].IsDefined()) {
      throw InputError(InputErrorKind::kMissingField, path, LineOf(ground),
                       "'" + name + ".camera_time_offset_s' needs '" + name + ".T_body_camera'");
    }
    if (ground["T_body_lidar"].IsDefined()) {
      LidarCalibration lidar;
      lidar.T_body_lidar = ReadTransform(doc, ground["T_body_lidar"], name + ".T_body_lidar");
      gt.ground_true_lidar = lidar;
    }
  }
  const YAML::Node air = true_calibration["air"];
  if (air.IsDefined() && !air.IsNull()) {
    if (!air.IsMap()) {
      throw InputError(InputErrorKind::kBadValue, path, LineOf(air),
                       "'true_calibration.air' must be a map from air agent name to a map");
    }
    for (const auto& kv : air) {
      CheckAgentName(doc, kv.first, "true_calibration.air", air_agents);
      const std::string agent = kv.first.Scalar();
      const std::string name = "true_calibration.air." + agent;
      if (gt.air_true_camera.count(agent)) {
        throw InputError(InputErrorKind::kMalformedRow, path, LineOf(kv.first),
                         "duplicate key '" + name + "'");
      }
      CheckMap(doc, kv.second, name, {"T_body_camera", "camera_time_offset_s"});
      CameraCalibration camera;
      camera.T_body_camera = ReadTransform(doc, Require(doc, kv.second, name, "T_body_camera"),
                                           name + ".T_body_camera");
      camera.time_offset_s = ReadOptionalDouble(doc, kv.second, name, "camera_time_offset_s", 0.0);
      gt.air_true_camera[agent] = camera;
    }
  }
  return gt;
}

}  // namespace internal

AgentCalibration ReadCalibration(const std::string& path, bool require_lidar) {
  using namespace internal;
  const YamlDoc doc = LoadYaml(path);
  CheckMap(doc, doc.root, "", {"camera", "lidar"});
  AgentCalibration calibration;
  const YAML::Node camera = Require(doc, doc.root, "", "camera");
  CheckMap(
      doc, camera, "camera",
      {"model", "width", "height", "intrinsics", "distortion", "T_body_camera", "time_offset_s"});
  calibration.camera.camera = ReadCameraParams(doc, camera);
  calibration.camera.T_body_camera =
      ReadTransform(doc, Require(doc, camera, "camera", "T_body_camera"), "camera.T_body_camera");
  calibration.camera.time_offset_s =
      ReadOptionalDouble(doc, camera, "camera", "time_offset_s", 0.0);

  const YAML::Node lidar = doc.root["lidar"];
  if (lidar.IsDefined()) {
    CheckMap(doc, lidar, "lidar", {"T_body_lidar", "time_offset_s"});
    LidarCalibration l;
    l.T_body_lidar =
        ReadTransform(doc, Require(doc, lidar, "lidar", "T_body_lidar"), "lidar.T_body_lidar");
    l.time_offset_s = ReadOptionalDouble(doc, lidar, "lidar", "time_offset_s", 0.0);
    calibration.lidar = l;
  } else if (require_lidar) {
    throw InputError(InputErrorKind::kMissingField, path, 0,
                     "required key 'lidar' is missing (the ground agent has a LiDAR)");
  }
  return calibration;
}

void WriteCalibration(const std::string& path, const AgentCalibration& calibration) {
  using namespace internal;
  const CameraParams& p = calibration.camera.camera;
  Camera validated(p);  // throws OptionError naming the field
  std::ostringstream out;
  out << "camera:\n"
      << "  model: " << p.model << "\n"
      << "  width: " << p.width << "\n"
      << "  height: " << p.height << "\n"
      << "  intrinsics: " << FormatList({p.fx, p.fy, p.cx, p.cy}) << "\n"
      << "  distortion: " << FormatList(p.distortion) << "\n"
      << "  T_body_camera: " << FormatTransform(calibration.camera.T_body_camera, 17) << "\n"
      << "  time_offset_s: " << FormatDouble(calibration.camera.time_offset_s) << "\n";
  if (calibration.lidar) {
    out << "lidar:\n"
        << "  T_body_lidar: " << FormatTransform(calibration.lidar->T_body_lidar, 16) << "\n"
        << "  time_offset_s: " << FormatDouble(calibration.lidar->time_offset_s) << "\n";
  }
  WriteTextFile(path, out.str());
}

DatasetGroundTruth ReadGroundTruth(const std::string& path) {
  return internal::ReadGroundTruthFor(path, nullptr);
}

void WriteGroundTruth(const std::string& path, const DatasetGroundTruth& groundtruth) {
  using namespace internal;
  std::ostringstream out;
  out << "T_wa_wg:" << (groundtruth.T_wa_wg.empty() ? " {}" : "") << "\n";
  for (const auto& [agent, T] : groundtruth.T_wa_wg) {
    if (!IsValidAgentName(agent)) {
      throw std::invalid_argument("groundtruth T_wa_wg: invalid air agent name '" + agent + "'");
    }
    const std::string key = "  " + agent + ": ";
    out << key << FormatTransform(T, static_cast<int>(key.size())) << "\n";
  }
  const bool has_ground = groundtruth.ground_true_camera || groundtruth.ground_true_lidar;
  if (has_ground || !groundtruth.air_true_camera.empty()) {
    out << "true_calibration:\n";
    if (has_ground) {
      out << "  ground:\n";
      if (groundtruth.ground_true_camera) {
        out << "    T_body_camera: "
            << FormatTransform(groundtruth.ground_true_camera->T_body_camera, 19) << "\n"
            << "    camera_time_offset_s: "
            << FormatDouble(groundtruth.ground_true_camera->time_offset_s) << "\n";
      }
      if (groundtruth.ground_true_lidar) {
        if (groundtruth.ground_true_lidar->time_offset_s != 0.0) {
          throw std::invalid_argument(
              "groundtruth.yaml has no true lidar time offset; ground_true_lidar->time_offset_s "
              "must be 0");
        }
        out << "    T_body_lidar: "
            << FormatTransform(groundtruth.ground_true_lidar->T_body_lidar, 18) << "\n";
      }
    }
    if (!groundtruth.air_true_camera.empty()) {
      out << "  air:\n";
      for (const auto& [agent, camera] : groundtruth.air_true_camera) {
        if (!IsValidAgentName(agent)) {
          throw std::invalid_argument("groundtruth true_calibration: invalid air agent name '" +
                                      agent + "'");
        }
        out << "    " << agent << ":\n"
            << "      T_body_camera: " << FormatTransform(camera.T_body_camera, 21) << "\n"
            << "      camera_time_offset_s: " << FormatDouble(camera.time_offset_s) << "\n";
      }
    }
  }
  WriteTextFile(path, out.str());
}

}  // namespace ag
