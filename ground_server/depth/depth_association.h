#pragma once

// Pixel-point correspondence: a 3-D point in the ground world for each UGV
// keypoint, from the LiDAR voxel map.
//
// Paper, "Pixel-Point Correspondence" (Lu et al.): "given a pixel p, a ray
// generated in camera coordinates is iterated along a specified depth range
// with a fixed step of 0.05 m, starting from shallower depths. At each step,
// the corresponding points are transformed to world coordinate. [...] For
// each converted point, the nearest neighbor is retrieved from the hash
// table. If no neighbor is found, the iteration proceeds to deeper points.
// When a neighbor is identified, the reprojected pixel p' is calculated [...]
// If the error exceeds a threshold, the iteration continues; otherwise, the
// nearest neighbor is transformed back to camera coordinates, and the
// perpendicular foot from the point to the ray serves as the precise 3D
// representation of the image feature pixel in camera coordinates."
//
// Here the ray is b = Unproject(p) (unit bearing, camera frame); sample k is
// at distance s_k = min_range_m + k * step_m along it, i.e. at
// o + s_k * R_wg_c b in the world (o = camera centre). For a neighbour q the
// 3-D point is the foot (b . q_c) b, q_c = T_c_wg q.
//
// AssociateReference does exactly that, sample by sample. Associate gives
// the same answers faster: it skips the samples outside the map's occupied
// bounds grown by one voxel, and every sample lying in an empty block of the
// map (VoxelGrid::EmptyBlockAt) - such a sample has
// no occupied voxel in its 27-neighbourhood, so the reference's query there
// finds nothing - jumping along the ray to where it leaves the block (a 3-D
// DDA step over blocks). Samples it does not skip are evaluated with
// the same arithmetic as the reference, so the two agree exactly; the
// test compares them on random scenes.

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/geometry/pose.h"
#include "ground_server/voxel_map/voxel_grid.h"

namespace ag {

/// The map point associated with one keypoint.
struct KeypointDepth {
  bool valid = false;                                 ///< false: the ray met no map point
  Eigen::Vector3d p_in_wg = Eigen::Vector3d::Zero();  ///< the 3-D point, ground world (m)
  Eigen::Vector3d p_c = Eigen::Vector3d::Zero();      ///< the same point, camera frame (m)
  double depth_m = 0.0;                               ///< p_c.z (m)
  double reprojection_error_px = 0.0;                 ///< of the map point that was accepted
};

/// Depths of a keyframe's keypoints, in keypoint order, with statistics.
struct DepthAssociationResult {
  std::vector<KeypointDepth> keypoints;
  size_t num_valid = 0;
  size_t samples_queried = 0;     ///< ray samples whose nearest neighbour was searched
  size_t samples_skipped = 0;     ///< samples skipped as empty space (Associate only)
  size_t skip_checks = 0;         ///< EmptyBlockAt lookups (Associate only)
  size_t neighbors_rejected = 0;  ///< neighbours found but reprojecting beyond the threshold

  double fraction_valid() const {
    return keypoints.empty() ? 0.0 : static_cast<double>(num_valid) / keypoints.size();
  }
};

class DepthAssociator {
 public:
  struct Options {
    double step_m = 0.05;             ///< march step along the ray (m); paper: 0.05
    double min_range_m = 0.3;         ///< first sample's distance from the camera centre (m)
    double max_range_m = 50.0;        ///< last sample's distance at most (m)
    double pixel_threshold_px = 2.0;  ///< max reprojection error of an accepted neighbour (px)
    int neighborhood = 27;            ///< voxels searched per sample: 7, 19 or 27
    /// Neighbours farther from the sample are ignored (m). Should cover the
    /// lateral tolerance pixel_threshold * range / f at far range (2 px at
    /// 50 m with f = 700 px: 0.14 m); beyond one voxel the 27-voxel search
    /// is no longer an exact nearest neighbour, which is iVox's trade-off.
    double max_neighbor_distance_m = 0.15;

    template <class V>
    void VisitFields(V& v) {
      v("step_m", step_m);
      v("min_range_m", min_range_m);
      v("max_range_m", max_range_m);
      v("pixel_threshold_px", pixel_threshold_px);
      v("neighborhood", neighborhood);
      v("max_neighbor_distance_m", max_neighbor_distance_m);
    }
    void Check() const;
  };

  /// Throws ag::OptionError if `options` are invalid.
  DepthAssociator(const Camera& camera, const Options& options);

  const Options& options() const { return options_; }

  /// Depth for every keypoint (pixels, distorted, as detected), skipping
  /// empty space. T_wg_c is the camera pose at the image time.
  DepthAssociationResult Associate(const VoxelGrid& map, const Pose& T_wg_c,
                                   const std::vector<Eigen::Vector2f>& keypoints) const;

  /// The paper's fixed-step march without skipping: the exact reference.
  DepthAssociationResult AssociateReference(const VoxelGrid& map, const Pose& T_wg_c,
                                            const std::vector<Eigen::Vector2f>& keypoints) const;

 private:
  struct Ray;
  struct Scratch;
  DepthAssociationResult Run(const VoxelGrid& map, const Pose& T_wg_c,
                             const std::vector<Eigen::Vector2f>& keypoints, bool skip) const;
  KeypointDepth MarchReference(const VoxelGrid& map, const Ray& ray,
                               DepthAssociationResult* stats) const;
  KeypointDepth MarchSkipping(const VoxelGrid& map, const Ray& ray, Scratch* scratch,
                              DepthAssociationResult* stats) const;
  /// The paper's acceptance test for the neighbour of one sample.
  bool Accept(const Ray& ray, const NearestResult& neighbor, KeypointDepth* out,
              DepthAssociationResult* stats) const;

  Camera camera_;
  Options options_;
  int num_samples_ = 0;
};

}  // namespace ag
