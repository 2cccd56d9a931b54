#include "tools/sim/odometry.h"

#include <cmath>

namespace ag {

void OdometryOptions::Check() const {
  CheckOption(rate_hz >= 10.0 && rate_hz <= 1000.0, "rate_hz",
              "must be in [10, 1000] (the spec asks >= 10 Hz)");
  CheckOption(yaw_random_walk_deg_per_sqrt_s >= 0, "yaw_random_walk_deg_per_sqrt_s",
              "must be >= 0");
  CheckOption(xy_random_walk_m_per_sqrt_s >= 0, "xy_random_walk_m_per_sqrt_s", "must be >= 0");
  CheckOption(z_random_walk_m_per_sqrt_s >= 0, "z_random_walk_m_per_sqrt_s", "must be >= 0");
  CheckOption(scale_error > -0.5 && scale_error < 0.5, "scale_error", "must be in (-0.5, 0.5)");
  CheckOption(position_noise_m >= 0, "position_noise_m", "must be >= 0");
  CheckOption(yaw_noise_deg >= 0, "yaw_noise_deg", "must be >= 0");
}

std::vector<StampedPose> SimulateOdometry(const std::vector<StampedPose>& truth,
                                          const OdometryOptions& o, SimRandom& rng) {
  constexpr double kDeg = M_PI / 180.0;
  std::vector<StampedPose> out;
  out.reserve(truth.size());
  if (truth.empty()) return out;
  double yaw = 0.0;
  Eigen::Vector3d q = truth.front().T.translation();
  for (size_t k = 0; k < truth.size(); ++k) {
    if (k > 0) {
      const double dt = static_cast<double>(truth[k].t_ns - truth[k - 1].t_ns) * 1e-9;
      const double sq = std::sqrt(dt);
      const Eigen::Vector3d dp = truth[k].T.translation() - truth[k - 1].T.translation();
      q += RotZ(yaw) * ((1.0 + o.scale_error) * dp);
      q += Eigen::Vector3d(o.xy_random_walk_m_per_sqrt_s * sq * rng.Gaussian(),
                           o.xy_random_walk_m_per_sqrt_s * sq * rng.Gaussian(),
                           o.z_random_walk_m_per_sqrt_s * sq * rng.Gaussian());
      yaw += o.yaw_drift_deg_per_min * kDeg / 60.0 * dt +
             o.yaw_random_walk_deg_per_sqrt_s * kDeg * sq * rng.Gaussian();
    }
    StampedPose s;
    s.t_ns = truth[k].t_ns;
    const double yaw_out =
        yaw + (k > 0 && o.yaw_noise_deg > 0 ? o.yaw_noise_deg * kDeg * rng.Gaussian() : 0.0);
    s.T.linear() = RotZ(yaw_out) * truth[k].T.linear();
    s.T.translation() = q;
    if (k > 0 && o.position_noise_m > 0) {
      s.T.translation() +=
          o.position_noise_m * Eigen::Vector3d(rng.Gaussian(), rng.Gaussian(), rng.Gaussian());
    }
    out.push_back(s);
  }
  return out;
}

}  // namespace ag
