#pragma once

// Odometry with drift, as LIO / VIO report it: the unobservable directions
// of a gravity-aligned odometry (x, y, z, yaw) drift; roll and pitch stay
// gravity-aligned (they are observable from the accelerometer).

#include <vector>

#include "common/core/error.h"
#include "common/geometry/pose.h"
#include "tools/sim/random.h"

namespace ag {

/// Drift model of one agent's odometry (scenario key `odometry`).
///
/// Integrated per step dt from the true poses p_k, R_k:
///   yaw_{k+1} = yaw_k + yaw_drift * dt + sigma_yaw * sqrt(dt) * n
///   q_{k+1}   = q_k + RotZ(yaw_k) (1 + scale_error) (p_{k+1} - p_k)
///               + [sigma_xy, sigma_xy, sigma_z] * sqrt(dt) * n
///   T_odom_k  = (RotZ(yaw_k) R_k, q_k) + white noise,
/// so after T seconds the yaw error is yaw_drift * T + N(0, sigma_yaw^2 T)
/// and, without yaw drift or scale error, each of x, y has error
/// N(0, sigma_xy^2 T).
struct OdometryOptions {
  double rate_hz = 100.0;                       ///< output rate (Hz)
  double yaw_drift_deg_per_min = 0.0;           ///< constant yaw drift rate, signed (deg/min)
  double yaw_random_walk_deg_per_sqrt_s = 0.0;  ///< yaw random walk (deg/sqrt(s))
  double xy_random_walk_m_per_sqrt_s = 0.0;     ///< horizontal position random walk (m/sqrt(s))
  double z_random_walk_m_per_sqrt_s = 0.0;      ///< vertical position random walk (m/sqrt(s))
  double scale_error = 0.0;                     ///< relative error of travelled distance (-)
  double position_noise_m = 0.0;                ///< white noise on each output position (m)
  double yaw_noise_deg = 0.0;                   ///< white noise on each output yaw (deg)

  template <class V>
  void VisitFields(V& v) {
    v("rate_hz", rate_hz);
    v("yaw_drift_deg_per_min", yaw_drift_deg_per_min);
    v("yaw_random_walk_deg_per_sqrt_s", yaw_random_walk_deg_per_sqrt_s);
    v("xy_random_walk_m_per_sqrt_s", xy_random_walk_m_per_sqrt_s);
    v("z_random_walk_m_per_sqrt_s", z_random_walk_m_per_sqrt_s);
    v("scale_error", scale_error);
    v("position_noise_m", position_noise_m);
    v("yaw_noise_deg", yaw_noise_deg);
  }
  void Check() const;
};

/// Odometry from true poses T_world_body (strictly increasing t_ns, the
/// odometry's sampling times). The first output equals the first true pose:
/// the odometry world is where the estimator started.
std::vector<StampedPose> SimulateOdometry(const std::vector<StampedPose>& truth,
                                          const OdometryOptions& options, SimRandom& rng);

}  // namespace ag
