#pragma once

// A simulation scenario (config/scenarios/*.yaml): the world, one ground
// agent (UGV: camera, spinning LiDAR, LIO odometry) and one or more air
// agents (UAV: oblique camera, VIO odometry). Read with the project's
// options machinery: unknown keys are rejected with file and line.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "tools/sim/lidar.h"
#include "tools/sim/odometry.h"
#include "tools/sim/renderer.h"
#include "tools/sim/trajectory.h"
#include "tools/sim/world.h"

namespace ag {

/// How far the true sensor calibration is from the nominal one written to
/// calibration.yaml. Each magnitude is drawn uniformly in [min, max] (seeded)
/// with a random direction / sign.
struct CalibrationErrorOptions {
  double rotation_min_deg = 0.0;  ///< extrinsic rotation error (deg)
  double rotation_max_deg = 0.0;
  double translation_min_m = 0.0;  ///< extrinsic translation error (m)
  double translation_max_m = 0.0;
  double time_offset_min_s = 0.0;  ///< camera time offset error (s)
  double time_offset_max_s = 0.0;

  template <class V>
  void VisitFields(V& v) {
    v("rotation_min_deg", rotation_min_deg);
    v("rotation_max_deg", rotation_max_deg);
    v("translation_min_m", translation_min_m);
    v("translation_max_m", translation_max_m);
    v("time_offset_min_s", time_offset_min_s);
    v("time_offset_max_s", time_offset_max_s);
  }
  void Check() const;
};

/// The UGV (scenario key `ground`).
struct GroundAgentOptions {
  double body_height_m = 0.3;  ///< body (IMU) frame height above the ground (m)
  double vibration_deg = 0.3;  ///< roll / pitch vibration amplitude (deg)
  PathOptions path;
  CameraSimOptions camera;
  LidarOptions lidar;
  OdometryOptions odometry;
  CalibrationErrorOptions calibration_error;
  /// The camera's and the LiDAR's mounting errors (rotation and translation)
  /// are each drawn from calibration_error, then scaled by these: 0 makes
  /// that sensor's nominal mounting exact, to see what each error costs.
  double camera_error_scale = 1.0;
  double lidar_error_scale = 1.0;

  GroundAgentOptions();
  template <class V>
  void VisitFields(V& v) {
    v("body_height_m", body_height_m);
    v("vibration_deg", vibration_deg);
    v("path", path);
    v("camera", camera);
    v("lidar", lidar);
    v("odometry", odometry);
    v("calibration_error", calibration_error);
    v("camera_error_scale", camera_error_scale);
    v("lidar_error_scale", lidar_error_scale);
  }
  void Check() const;
};

/// One UAV (scenario key `air.<name>`).
struct AirAgentOptions {
  double altitude_m = 8.0;            ///< flight altitude of the body above the ground (m)
  double altitude_variation_m = 0.5;  ///< slow altitude oscillation amplitude (m)
  double vibration_deg = 0.2;         ///< roll / pitch vibration on top of the tilt (deg)
  double clock_offset_s = 0.0;        ///< this agent's clock minus the ground clock (s)
  PathOptions path;
  CameraSimOptions camera;
  OdometryOptions odometry;
  CalibrationErrorOptions calibration_error;

  AirAgentOptions();
  template <class V>
  void VisitFields(V& v) {
    v("altitude_m", altitude_m);
    v("altitude_variation_m", altitude_variation_m);
    v("vibration_deg", vibration_deg);
    v("clock_offset_s", clock_offset_s);
    v("path", path);
    v("camera", camera);
    v("odometry", odometry);
    v("calibration_error", calibration_error);
  }
  void Check() const;
};

/// Everything but the air agents (which are a map keyed by agent name).
struct ScenarioOptions {
  std::string name = "scenario";                ///< dataset name
  std::string description;                      ///< free text for dataset.yaml
  double duration_s = 60.0;                     ///< simulated time (s)
  int64_t start_time_ns = 1700000000000000000;  ///< ground clock at the start (ns)
  double air_world_offset_xy_m =
      5.0;  ///< each wa origin is this far (uniform) from the air start, per axis (m)
  double air_world_offset_z_m = 1.0;  ///< and this far vertically (m); its yaw is uniform
  WorldOptions world;
  GroundAgentOptions ground;

  template <class V>
  void VisitFields(V& v) {
    v("name", name);
    v("description", description);
    v("duration_s", duration_s);
    v("start_time_ns", start_time_ns);
    v("air_world_offset_xy_m", air_world_offset_xy_m);
    v("air_world_offset_z_m", air_world_offset_z_m);
    v("world", world);
    v("ground", ground);
  }
  void Check() const;
};

struct Scenario {
  ScenarioOptions options;
  std::map<std::string, AirAgentOptions> air;  ///< by agent name ([a-z0-9_]+), sorted
};

/// Reads a scenario file. Throws ag::InputError naming the file, line and
/// key on a missing file, bad YAML, an unknown key or an invalid value.
Scenario LoadScenario(const std::string& path);

/// The scenario as YAML text (effective values), for the dataset's record.
std::string ScenarioToYaml(const Scenario& scenario);

}  // namespace ag
