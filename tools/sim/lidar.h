#pragma once

// A spinning multi-beam LiDAR (Ouster / Velodyne style) ray-cast into the
// simulated world. Each column fires at its own time while the platform
// moves; points are then motion-compensated exactly into the LiDAR frame at
// the scan timestamp (the end of the sweep), as a LIO front end expects.

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "common/core/error.h"
#include "common/geometry/pose.h"
#include "tools/sim/random.h"
#include "tools/sim/world.h"

namespace ag {

/// LiDAR model and nominal mounting (scenario key `ground.lidar`).
struct LidarOptions {
  int beams = 64;                                     ///< vertical channels (32-128)
  int columns = 1024;                                 ///< firings per revolution
  double rate_hz = 10.0;                              ///< revolutions per second (Hz)
  double vfov_min_deg = -22.5;                        ///< lowest beam elevation (deg)
  double vfov_max_deg = 22.5;                         ///< highest beam elevation (deg)
  double min_range_m = 0.5;                           ///< returns closer than this are dropped (m)
  double max_range_m = 100.0;                         ///< no return beyond (m)
  double range_noise_m = 0.02;                        ///< range noise standard deviation (m)
  double dropout = 0.01;                              ///< probability a return is lost
  std::vector<double> position_m = {0.0, 0.0, 0.45};  ///< nominal position in the body frame (m)
  double yaw_deg = 0.0;                               ///< nominal mounting yaw about body z (deg)
  double time_offset_s = 0.0;                         ///< nominal t_body = t_lidar + offset (s)

  template <class V>
  void VisitFields(V& v) {
    v("beams", beams);
    v("columns", columns);
    v("rate_hz", rate_hz);
    v("vfov_min_deg", vfov_min_deg);
    v("vfov_max_deg", vfov_max_deg);
    v("min_range_m", min_range_m);
    v("max_range_m", max_range_m);
    v("range_noise_m", range_noise_m);
    v("dropout", dropout);
    v("position_m", position_m);
    v("yaw_deg", yaw_deg);
    v("time_offset_s", time_offset_s);
  }
  void Check() const;
};

/// One simulated sweep, in the LiDAR frame at the scan time.
struct LidarSweep {
  std::vector<Eigen::Vector3f> points;  ///< (m)
  std::vector<float> intensity;         ///< 0..255, from albedo and incidence
};

/// Simulates the sweep that ends at true time `tau_end` (s): column c fires
/// at tau_end - (1 - c / columns) / rate_hz from T_W_lidar(tau). Points are
/// expressed in the LiDAR frame at tau_end.
LidarSweep SimulateLidarSweep(const SimWorld& world, const LidarOptions& options,
                              const std::function<Pose(double)>& T_W_lidar, double tau_end,
                              SimRandom& rng);

}  // namespace ag
