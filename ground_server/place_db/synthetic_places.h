#pragma once

// Synthetic place descriptors with the structure of real ones, for tests and
// benchmarks of the place database.
//
// Uniform random unit vectors in 512-D are the worst case for any
// approximate nearest-neighbour search (all pairwise similarities ~0, no
// neighbourhood structure) and nothing like a place-recognition descriptor.
// A real global descriptor (MixVPR) is a smooth function of where the camera
// is and where it looks, plus appearance noise: consecutive keyframes are
// similar, revisits are similar, distant places are not. This models that:
//
//   d(p, yaw) = normalise( phi(p, yaw) + noise * n ),   n ~ N(0, I / dim)
//   phi_j     = sqrt(2 / dim) * cos(w_j . u + b_j),    u = (p / place_scale,
//               cos(yaw) / yaw_scale, sin(yaw) / yaw_scale)
//
// with w_j ~ N(0, I), b_j ~ U(0, 2 pi): random Fourier features, so
// <phi(a), phi(b)> ~ exp(-|u_a - u_b|^2 / 2) (a Gaussian kernel over place and
// heading, Rahimi & Recht 2007).

#include <cstdint>
#include <random>
#include <vector>

#include "common/geometry/pose.h"
#include "common/types/keyframe.h"

namespace ag {

class SyntheticPlaces {
 public:
  struct Options {
    int dim = 512;               ///< descriptor length
    double place_scale_m = 8.0;  ///< distance at which similarity drops to exp(-1/2) (m)
    double yaw_scale_rad = 0.6;  ///< the same for heading, on the unit circle (rad)
    uint32_t seed = 7;           ///< seed of the feature frequencies (the "world")
  };

  explicit SyntheticPlaces(Options options);

  /// Descriptor of a camera at `p_w` (m) heading `yaw` (rad), with
  /// appearance noise of relative size `noise` drawn from `rng`.
  std::vector<float> Descriptor(const Eigen::Vector3d& p_w, double yaw, double noise,
                                std::mt19937& rng) const;

  /// Descriptor of a camera pose (heading = yaw of the camera's optical axis).
  std::vector<float> Descriptor(const Pose& T_w_c, double noise, std::mt19937& rng) const;

 private:
  Options options_;
  std::vector<float> w_;  ///< dim x 5 frequencies, row-major
  std::vector<float> b_;  ///< dim phases
};

/// Camera poses (OpenCV camera axes, looking ahead and 30 deg down) of a UAV
/// flying a smooth random path at `step_m` per keyframe over a square of
/// `area_m`, turning back at the borders, so that long flights revisit places.
std::vector<Pose> SyntheticFlight(int keyframes, double step_m, double area_m, uint32_t seed);

/// Uniformly random unit vectors (the worst case for HNSW).
std::vector<float> RandomUnitVector(int dim, std::mt19937& rng);

/// A keyframe with the given descriptor and pose and `keypoints` random
/// keypoints with `local_dim`-D float descriptors (0 keypoints: none).
AirKeyframe SyntheticKeyframe(const std::string& agent, int64_t seq, const Pose& T_wa_c,
                              std::vector<float> global, int keypoints, int local_dim,
                              std::mt19937& rng);

}  // namespace ag
