#include "tools/sim/scenario.h"

#include <yaml-cpp/yaml.h>

#include "common/config/options.h"
#include "common/dataset/dataset.h"

namespace ag {

void CalibrationErrorOptions::Check() const {
  CheckOption(
      rotation_min_deg >= 0 && rotation_max_deg >= rotation_min_deg && rotation_max_deg < 20,
      "rotation_max_deg", "need 0 <= rotation_min_deg <= rotation_max_deg < 20");
  CheckOption(
      translation_min_m >= 0 && translation_max_m >= translation_min_m && translation_max_m < 1,
      "translation_max_m", "need 0 <= translation_min_m <= translation_max_m < 1");
  CheckOption(
      time_offset_min_s >= 0 && time_offset_max_s >= time_offset_min_s && time_offset_max_s < 0.5,
      "time_offset_max_s", "need 0 <= time_offset_min_s <= time_offset_max_s < 0.5");
}

GroundAgentOptions::GroundAgentOptions() {
  path.shape = "orbit";
  path.radius_m = 8.0;
  path.speed_mps = 1.2;
  camera.position_m = {0.25, 0.0, 0.2};  // 0.5 m above the ground with body_height_m 0.3
  camera.depth = false;
  odometry.rate_hz = 100.0;
  odometry.yaw_drift_deg_per_min = 0.5;
  odometry.yaw_random_walk_deg_per_sqrt_s = 0.01;
  odometry.xy_random_walk_m_per_sqrt_s = 0.003;
  odometry.z_random_walk_m_per_sqrt_s = 0.002;
  odometry.scale_error = 0.002;
  odometry.position_noise_m = 0.002;
  odometry.yaw_noise_deg = 0.02;
  calibration_error.rotation_min_deg = 0.5;
  calibration_error.rotation_max_deg = 1.0;
  calibration_error.translation_min_m = 0.01;
  calibration_error.translation_max_m = 0.03;
  calibration_error.time_offset_min_s = 0.01;
  calibration_error.time_offset_max_s = 0.02;
}

void GroundAgentOptions::Check() const {
  CheckOption(body_height_m > 0.05 && body_height_m < 3.0, "body_height_m", "must be in (0.05, 3)");
  CheckOption(vibration_deg >= 0 && vibration_deg < 5, "vibration_deg", "must be in [0, 5)");
  CheckOption(camera_error_scale >= 0 && camera_error_scale <= 10, "camera_error_scale",
              "must be in [0, 10]");
  CheckOption(lidar_error_scale >= 0 && lidar_error_scale <= 10, "lidar_error_scale",
              "must be in [0, 10]");
}

AirAgentOptions::AirAgentOptions() {
  path.shape = "orbit";
  path.radius_m = 10.0;
  path.speed_mps = 2.5;
  path.heading = "look_at";
  camera.fx = 400.0;
  camera.fy = 400.0;
  camera.distortion = {-0.03, 0.008, -0.0002, 0.0003};
  camera.position_m = {0.1, 0.0, -0.05};
  camera.pitch_down_deg = 45.0;
  camera.read_noise_dn = 0.9;
  camera.shot_noise_dn = 0.12;
  camera.blur_sigma_px = 0.7;
  camera.vignetting = 0.35;
  odometry.rate_hz = 200.0;
  odometry.yaw_drift_deg_per_min = 0.8;
  odometry.yaw_random_walk_deg_per_sqrt_s = 0.02;
  odometry.xy_random_walk_m_per_sqrt_s = 0.01;
  odometry.z_random_walk_m_per_sqrt_s = 0.005;
  odometry.scale_error = 0.005;
  odometry.position_noise_m = 0.003;
  odometry.yaw_noise_deg = 0.03;
  calibration_error.rotation_max_deg = 0.2;
  calibration_error.translation_max_m = 0.005;
  calibration_error.time_offset_max_s = 0.002;
}

void AirAgentOptions::Check() const {
  CheckOption(altitude_m >= 1.0 && altitude_m <= 120.0, "altitude_m", "must be in [1, 120]");
  CheckOption(altitude_variation_m >= 0 && altitude_variation_m < 0.5 * altitude_m,
              "altitude_variation_m", "must be in [0, altitude_m / 2)");
  CheckOption(vibration_deg >= 0 && vibration_deg < 5, "vibration_deg", "must be in [0, 5)");
  CheckOption(std::abs(clock_offset_s) < 1e6, "clock_offset_s", "must be below 1e6 s in magnitude");
}

void ScenarioOptions::Check() const {
  CheckOption(duration_s > 0 && duration_s <= 3600, "duration_s", "must be in (0, 3600]");
  CheckOption(start_time_ns >= 0, "start_time_ns", "must be >= 0");
  CheckOption(air_world_offset_xy_m >= 0 && air_world_offset_z_m >= 0, "air_world_offset_xy_m",
              "must be >= 0");
}

Scenario LoadScenario(const std::string& path) {
  const YAML::Node root = LoadYamlFile(path);
  if (!root.IsMap())
    throw InputError(InputErrorKind::kBadValue, path, 1, "a scenario must be a YAML map");
  // The air agents are a map keyed by name, which the options machinery does
  // not model: read every other key as ScenarioOptions, then each agent.
  YAML::Node rest(YAML::NodeType::Map);
  YAML::Node air;
  for (const auto& kv : root) {
    if (kv.first.as<std::string>() == "air") {
      air = kv.second;
    } else {
      rest.force_insert(kv.first, kv.second);
    }
  }
  Scenario scenario;
  scenario.options = LoadOptions<ScenarioOptions>(rest, path);
  if (!air.IsDefined() || !air.IsMap() || air.size() == 0) {
    throw InputError(InputErrorKind::kMissingField, path, air.IsDefined() ? air.Mark().line + 1 : 0,
                     "'air' must map at least one agent name to its options");
  }
  for (const auto& kv : air) {
    const std::string name = kv.first.as<std::string>();
    if (!IsValidAgentName(name) || name == "ground") {
      throw InputError(InputErrorKind::kBadValue, path, kv.first.Mark().line + 1,
                       "air agent name '" + name + "' must be [a-z0-9_]+ and not 'ground'");
    }
    scenario.air[name] = LoadOptions<AirAgentOptions>(kv.second, path, "air." + name);
  }
  return scenario;
}

std::string ScenarioToYaml(const Scenario& scenario) {
  YAML::Node node = OptionsToYaml(scenario.options);
  YAML::Node air(YAML::NodeType::Map);
  for (const auto& [name, options] : scenario.air) air[name] = OptionsToYaml(options);
  node["air"] = air;
  YAML::Emitter out;
  out << node;
  return std::string(out.c_str()) + "\n";
}

}  // namespace ag
