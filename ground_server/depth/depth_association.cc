#include "ground_server/depth/depth_association.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

namespace ag {

/// One keypoint's ray: bearing in the camera, origin and direction in the
/// world, and the pose to bring neighbours back into the camera.
struct DepthAssociator::Ray {
  Eigen::Vector2d uv;
  Eigen::Vector3d b_c;      ///< unit bearing, camera frame
  Eigen::Vector3d o_in_wg;  ///< camera centre, world
  Eigen::Vector3d d_in_wg;  ///< R_wg_c * b_c
  const Pose* T_wg_c = nullptr;
  Eigen::Matrix3d R_c_wg;
};

/// Per-call memory of the skipping march. Valid because the map does not
/// change during one Associate() call (the caller holds a VoxelMap::Reader).
struct DepthAssociator::Scratch {
  VoxelGrid::LookupCache cache;
};

namespace {

// Distance (m) by which block boxes are shrunk before a skip, far above the
// rounding of sample positions (~1e-11 m at 100 km) so that every skipped
// sample's computed voxel provably lies in the block (see MarchSkipping).
constexpr double kSkipMargin = 1e-6;

}  // namespace

void DepthAssociator::Options::Check() const {
  CheckOption(std::isfinite(step_m) && step_m > 0, "step_m", "must be > 0");
  CheckOption(std::isfinite(min_range_m) && min_range_m >= 0, "min_range_m", "must be >= 0");
  CheckOption(std::isfinite(max_range_m) && max_range_m > min_range_m, "max_range_m",
              "must be > min_range_m");
  CheckOption((max_range_m - min_range_m) / step_m <= 1e6, "step_m",
              "gives more than 10^6 samples per ray");
  CheckOption(std::isfinite(pixel_threshold_px) && pixel_threshold_px > 0, "pixel_threshold_px",
              "must be > 0");
  CheckOption(neighborhood == 7 || neighborhood == 19 || neighborhood == 27, "neighborhood",
              "must be 7, 19 or 27");
  CheckOption(std::isfinite(max_neighbor_distance_m) && max_neighbor_distance_m > 0,
              "max_neighbor_distance_m", "must be > 0");
}

DepthAssociator::DepthAssociator(const Camera& camera, const Options& options)
    : camera_(camera), options_(options) {
  options_.Check();
  num_samples_ = static_cast<int>(std::floor(
                     (options_.max_range_m - options_.min_range_m) / options_.step_m + 1e-9)) +
                 1;
}

DepthAssociationResult DepthAssociator::Associate(
    const VoxelGrid& map, const Pose& T_wg_c, const std::vector<Eigen::Vector2f>& keypoints) const {
  return Run(map, T_wg_c, keypoints, /*skip=*/true);
}

DepthAssociationResult DepthAssociator::AssociateReference(
    const VoxelGrid& map, const Pose& T_wg_c, const std::vector<Eigen::Vector2f>& keypoints) const {
  return Run(map, T_wg_c, keypoints, /*skip=*/false);
}

DepthAssociationResult DepthAssociator::Run(const VoxelGrid& map, const Pose& T_wg_c,
                                            const std::vector<Eigen::Vector2f>& keypoints,
                                            bool skip) const {
  DepthAssociationResult result;
  result.keypoints.resize(keypoints.size());
  // ~12 KB of cache: on the heap, once per call.
  const auto scratch = std::make_unique<Scratch>();
  Ray ray;
  ray.T_wg_c = &T_wg_c;
  ray.o_in_wg = T_wg_c.translation();
  ray.R_c_wg = T_wg_c.linear().transpose();
  for (size_t i = 0; i < keypoints.size(); ++i) {
    ray.uv = keypoints[i].cast<double>();
    if (!ray.uv.allFinite()) continue;
    ray.b_c = camera_.Unproject(ray.uv);
    ray.d_in_wg = T_wg_c.linear() * ray.b_c;
    result.keypoints[i] =
        skip ? MarchSkipping(map, ray, scratch.get(), &result) : MarchReference(map, ray, &result);
    if (result.keypoints[i].valid) ++result.num_valid;
  }
  return result;
}

bool DepthAssociator::Accept(const Ray& ray, const NearestResult& neighbor, KeypointDepth* out,
                             DepthAssociationResult* stats) const {
  const Eigen::Vector3d q_c = ray.R_c_wg * (neighbor.point.cast<double>() - ray.o_in_wg);
  Eigen::Vector2d uv;
  const double along = ray.b_c.dot(q_c);
  if (!camera_.Project(q_c, &uv) || along <= 0) {
    ++stats->neighbors_rejected;
    return false;
  }
  const double error_px = (uv - ray.uv).norm();
  if (!(error_px <= options_.pixel_threshold_px)) {
    ++stats->neighbors_rejected;
    return false;
  }
  // Foot of the perpendicular from q_c to the ray through the origin.
  out->valid = true;
  out->p_c = along * ray.b_c;
  out->p_in_wg = *ray.T_wg_c * out->p_c;
  out->depth_m = out->p_c.z();
  out->reprojection_error_px = error_px;
  return true;
}

namespace {

// Sample k of a ray, written once so both marches compute bit-identical
// positions.
inline Eigen::Vector3d SamplePoint(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                   double min_range, double step, int k) {
  const double s = min_range + k * step;
  return o + s * d;
}

}  // namespace

KeypointDepth DepthAssociator::MarchReference(const VoxelGrid& map, const Ray& ray,
                                              DepthAssociationResult* stats) const {
  KeypointDepth out;
  for (int k = 0; k < num_samples_; ++k) {
    const Eigen::Vector3d p =
        SamplePoint(ray.o_in_wg, ray.d_in_wg, options_.min_range_m, options_.step_m, k);
    ++stats->samples_queried;
    const NearestResult neighbor =
        map.Nearest(p, options_.neighborhood, options_.max_neighbor_distance_m);
    if (neighbor.found && Accept(ray, neighbor, &out, stats)) return out;
  }
  return out;
}

// Why skipping cannot change the answer: a sample is skipped only when it
// lies in a block B returned by EmptyBlockAt, i.e. no occupied voxel within
// one voxel of B, so the reference's query from it (over <= 27
// voxels around its own voxel in B) finds nothing. Sample k's own voxel was
// computed exactly as the reference computes it. The later samples skipped
// with it are those with s_k < s < s_exit of B shrunk by kSkipMargin, and
// only when s_k is already inside that shrunk box: they lie strictly inside
// it, farther from its faces than any rounding of their position, so their
// computed voxels are in B too. Likewise the samples clipped away lie outside
// the occupied bounds grown by one voxel plus the same margin.
KeypointDepth DepthAssociator::MarchSkipping(const VoxelGrid& map, const Ray& ray, Scratch* scratch,
                                             DepthAssociationResult* stats) const {
  KeypointDepth out;
  const double voxel_size = map.options().voxel_size_m;
  const Eigen::Vector3d& o = ray.o_in_wg;
  const Eigen::Vector3d& d = ray.d_in_wg;
  const double min_range = options_.min_range_m;
  const double step = options_.step_m;

  // First sample index after k that may lie outside the empty `block`.
  auto next_sample_outside = [&](int k, const VoxelGrid::EmptyBlock& block) {
    double s_enter = -std::numeric_limits<double>::infinity();
    double s_exit = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      const double lo = block.first[a] * voxel_size + kSkipMargin;
      const double hi = (block.first[a] + block.edge_voxels) * voxel_size - kSkipMargin;
      if (d[a] > 0) {
        s_enter = std::max(s_enter, (lo - o[a]) / d[a]);
        s_exit = std::min(s_exit, (hi - o[a]) / d[a]);
      } else if (d[a] < 0) {
        s_enter = std::max(s_enter, (hi - o[a]) / d[a]);
        s_exit = std::min(s_exit, (lo - o[a]) / d[a]);
      } else if (o[a] <= lo || o[a] >= hi) {
        return k + 1;
      }
    }
    const double s_k = min_range + k * step;
    if (!(s_enter < s_k && s_k < s_exit)) return k + 1;
    // Smallest j with s_j >= s_exit, guarding the division's rounding.
    const double j_estimate = std::ceil((s_exit - min_range) / step);
    int j = j_estimate >= num_samples_ ? num_samples_ : static_cast<int>(j_estimate);
    j = std::max(j, k + 1);
    while (j > k + 1 && min_range + (j - 1) * step >= s_exit) --j;
    while (j < num_samples_ && min_range + j * step < s_exit) ++j;
    return j;
  };

  // Clip the march to the occupied bounds grown by one voxel (+ margin):
  // outside, no sample has an occupied voxel in its neighbourhood.
  int k = 0;
  int end = num_samples_;
  VoxelIndex lo, hi;
  if (!map.OccupiedBounds(&lo, &hi)) {
    stats->samples_skipped += static_cast<size_t>(num_samples_);
    return out;
  }
  {
    double s_enter = -std::numeric_limits<double>::infinity();
    double s_exit = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
      const double box_lo = (lo[a] - 1) * voxel_size - kSkipMargin;
      const double box_hi = (hi[a] + 2) * voxel_size + kSkipMargin;
      if (d[a] > 0) {
        s_enter = std::max(s_enter, (box_lo - o[a]) / d[a]);
        s_exit = std::min(s_exit, (box_hi - o[a]) / d[a]);
      } else if (d[a] < 0) {
        s_enter = std::max(s_enter, (box_hi - o[a]) / d[a]);
        s_exit = std::min(s_exit, (box_lo - o[a]) / d[a]);
      } else if (o[a] < box_lo || o[a] > box_hi) {
        s_exit = -std::numeric_limits<double>::infinity();
      }
    }
    // Samples with s < s_enter or s > s_exit are outside the grown box.
    if (s_enter > min_range) {
      const double first = std::ceil((s_enter - min_range) / step);
      k = first < num_samples_ ? static_cast<int>(first) : num_samples_;
      while (k > 0 && min_range + (k - 1) * step >= s_enter) --k;
      while (k < num_samples_ && min_range + k * step < s_enter) ++k;
    }
    if (s_exit < min_range) {
      end = 0;
    } else if (std::isfinite(s_exit)) {
      const double last = std::floor((s_exit - min_range) / step);
      end = last + 1 < num_samples_ ? static_cast<int>(last) + 1 : num_samples_;
      while (end > 0 && min_range + (end - 1) * step > s_exit) --end;
      while (end < num_samples_ && min_range + end * step <= s_exit) ++end;
    }
    end = std::max(end, k);
    stats->samples_skipped += static_cast<size_t>(k);
  }
  while (k < end) {
    const Eigen::Vector3d p = SamplePoint(o, d, min_range, step, k);
    const VoxelIndex voxel = map.VoxelOf(p);
    ++stats->skip_checks;
    const VoxelGrid::EmptyBlock empty = map.EmptyBlockAt(voxel);
    if (empty.edge_voxels > 0) {
      const int next = std::min(next_sample_outside(k, empty), end);
      stats->samples_skipped += static_cast<size_t>(next - k);
      k = next;
      continue;
    }
    ++stats->samples_queried;
    const NearestResult neighbor =
        map.Nearest(p, options_.neighborhood, options_.max_neighbor_distance_m, &scratch->cache);
    if (neighbor.found && Accept(ray, neighbor, &out, stats)) return out;
    ++k;
  }
  stats->samples_skipped += static_cast<size_t>(num_samples_ - end);
  return out;
}

}  // namespace ag
