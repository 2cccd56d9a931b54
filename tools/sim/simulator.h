#pragma once

// The scenario simulator: builds the world and the agents' true motion and
// calibration from a scenario and a seed, and writes a dataset in format v1
// (../shared/spec/dataset.md). Output is a pure function of (scenario, seed,
// texture folder): every random draw comes from a stream named after what it
// is for, and frames rendered in parallel write only their own files.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/geometry/pose.h"
#include "tools/sim/renderer.h"
#include "tools/sim/scenario.h"
#include "tools/sim/texture.h"
#include "tools/sim/trajectory.h"
#include "tools/sim/world.h"

namespace ag {

/// The true state of one simulated agent.
struct SimAgent {
  std::string name;  ///< "ground" or the air agent name
  bool ground = false;
  std::unique_ptr<AgentMotion> motion;  ///< T_W_body(tau)
  Pose T_W_world = Pose::Identity();    ///< T_W_wg or T_W_wa
  int64_t clock_start_ns = 0;           ///< the agent's clock at tau = 0
  CameraSimOptions camera_options;
  std::unique_ptr<CameraRenderer> renderer;
  Pose T_body_camera_nominal = Pose::Identity();
  Pose T_body_camera_true = Pose::Identity();
  double camera_offset_nominal_s = 0.0;  ///< t_body = t_camera + offset
  double camera_offset_true_s = 0.0;
  Pose T_body_lidar_nominal = Pose::Identity();  ///< ground only
  Pose T_body_lidar_true = Pose::Identity();
  double lidar_offset_s = 0.0;  ///< nominal = true
  OdometryOptions odometry;

  /// True time (s since start) of an instant of this agent's clock.
  double Tau(int64_t t_ns) const { return static_cast<double>(t_ns - clock_start_ns) * 1e-9; }
  /// The agent's clock at true time tau.
  int64_t ClockNs(double tau) const;
  /// True T_W_camera of the image stamped t_camera_ns (camera clock).
  Pose CameraPoseAtStamp(int64_t t_camera_ns) const;
};

class Simulation {
 public:
  /// Builds world and agents. `textures_dir` empty = procedural textures.
  /// Throws ag::InputError for a bad texture folder.
  Simulation(const Scenario& scenario, uint64_t seed, const std::string& textures_dir = "");
  ~Simulation();

  /// Writes the dataset to `out_dir` (must not exist or be empty) using
  /// `threads` workers (0 = all cores). Returns the number of files written.
  size_t Write(const std::string& out_dir, int threads = 0) const;

  /// Writes one PNG with an air view (left) and the ground view (right) of
  /// the same place. `tau_s` < 0 picks the instant where an air camera sees
  /// the spot the ground camera looks at closest to its image centre.
  /// Returns the chosen time (s).
  double WritePreview(const std::string& png_path, double tau_s = -1.0) const;

  const SimWorld& world() const { return *world_; }
  const Scenario& scenario() const { return scenario_; }
  const SimAgent& ground() const { return *agents_.front(); }
  /// Ground first, then the air agents in name order.
  const std::vector<std::unique_ptr<SimAgent>>& agents() const { return agents_; }
  uint64_t seed() const { return seed_; }

 private:
  Scenario scenario_;
  uint64_t seed_;
  std::unique_ptr<TextureImages> images_;
  std::unique_ptr<SimWorld> world_;
  std::vector<std::unique_ptr<SimAgent>> agents_;
};

}  // namespace ag
