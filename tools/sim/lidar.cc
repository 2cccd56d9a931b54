#include "tools/sim/lidar.h"

#include <cmath>

namespace ag {

void LidarOptions::Check() const {
  CheckOption(beams >= 1 && beams <= 256, "beams", "must be in [1, 256]");
  CheckOption(columns >= 16 && columns <= 8192, "columns", "must be in [16, 8192]");
  CheckOption(rate_hz > 0 && rate_hz <= 50, "rate_hz", "must be in (0, 50]");
  CheckOption(vfov_max_deg >= vfov_min_deg && vfov_min_deg > -90 && vfov_max_deg < 90,
              "vfov_max_deg", "need -90 < vfov_min_deg <= vfov_max_deg < 90");
  CheckOption(min_range_m >= 0 && max_range_m > min_range_m, "max_range_m",
              "must be > min_range_m >= 0");
  CheckOption(range_noise_m >= 0, "range_noise_m", "must be >= 0");
  CheckOption(dropout >= 0 && dropout < 1, "dropout", "must be in [0, 1)");
  CheckOption(position_m.size() == 3, "position_m", "must be [x, y, z]");
}

LidarSweep SimulateLidarSweep(const SimWorld& world, const LidarOptions& o,
                              const std::function<Pose(double)>& T_W_lidar, double tau_end,
                              SimRandom& rng) {
  constexpr double kDeg = M_PI / 180.0;
  const double period = 1.0 / o.rate_hz;
  const Pose T_lidar_W_end = T_W_lidar(tau_end).inverse();
  std::vector<double> cos_el(static_cast<size_t>(o.beams)), sin_el(static_cast<size_t>(o.beams));
  for (int b = 0; b < o.beams; ++b) {
    const double el =
        o.beams == 1
            ? o.vfov_min_deg * kDeg
            : (o.vfov_min_deg + (o.vfov_max_deg - o.vfov_min_deg) * b / (o.beams - 1)) * kDeg;
    cos_el[static_cast<size_t>(b)] = std::cos(el);
    sin_el[static_cast<size_t>(b)] = std::sin(el);
  }
  // Beam divergence ~ one column wide: the footprint that filters the albedo.
  const double divergence = 2.0 * M_PI / o.columns;
  LidarSweep sweep;
  sweep.points.reserve(static_cast<size_t>(o.beams) * o.columns);
  sweep.intensity.reserve(sweep.points.capacity());
  RayHit hit;
  for (int c = 0; c < o.columns; ++c) {
    const double tau = tau_end - period * (1.0 - static_cast<double>(c) / o.columns);
    const Pose T = T_W_lidar(tau);
    // Clockwise from behind, like an Ouster sensor.
    const double az = M_PI - 2.0 * M_PI * c / o.columns;
    const double ca = std::cos(az), sa = std::sin(az);
    const Pose T_end_c = T_lidar_W_end * T;  // this column's LiDAR frame -> the frame at tau_end
    for (int b = 0; b < o.beams; ++b) {
      const Eigen::Vector3d d_l(cos_el[static_cast<size_t>(b)] * ca,
                                cos_el[static_cast<size_t>(b)] * sa,
                                sin_el[static_cast<size_t>(b)]);
      const Eigen::Vector3d d_w = T.linear() * d_l;
      const double noise = rng.Gaussian();
      const double drop = rng.Uniform();
      if (!world.Cast(T.translation(), d_w, o.max_range_m, &hit)) continue;
      if (hit.t < o.min_range_m || drop < o.dropout) continue;
      const double range = hit.t + o.range_noise_m * noise;
      const Eigen::Vector3d p = T_end_c * (range * d_l);
      const Eigen::Vector3f albedo = world.Albedo(hit, std::max(hit.t * divergence, 1e-3));
      const double lum = 0.2126 * albedo.x() + 0.7152 * albedo.y() + 0.0722 * albedo.z();
      const double incidence = std::fabs(hit.n.dot(d_w));
      sweep.points.push_back(p.cast<float>());
      sweep.intensity.push_back(
          static_cast<float>(std::min(255.0, 400.0 * lum * (0.3 + 0.7 * incidence))));
    }
  }
  return sweep;
}

}  // namespace ag
