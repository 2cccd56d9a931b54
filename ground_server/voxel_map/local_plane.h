#pragma once

// The surface of the LiDAR map around a point, for anchoring camera points to
// the map (stage 1's point-to-plane term): a least-squares plane through the
// map points near it, kept only where the neighbourhood really is flat.

#include <Eigen/Core>
#include <optional>

#include "common/core/error.h"
#include "ground_server/voxel_map/voxel_grid.h"

namespace ag {

struct LocalPlane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    ///< centroid of the fitted points (wg)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit normal (sign arbitrary)
  double rms_m = 0;                                   ///< rms distance of the points to it (m)
  int num_points = 0;
};

struct LocalPlaneOptions {
  double radius_m = 0.2;          ///< points within this distance of the query are fitted (m)
  int min_points = 8;             ///< fewer: no plane
  double max_rms_m = 0.03;        ///< thicker neighbourhoods (edges, clutter) give no plane (m)
  double min_extent_ratio = 0.3;  ///< second over first principal spread: a line is no plane

  template <class V>
  void VisitFields(V& v) {
    v("radius_m", radius_m);
    v("min_points", min_points);
    v("max_rms_m", max_rms_m);
    v("min_extent_ratio", min_extent_ratio);
  }
  void Check() const;
};

/// Plane of the map points within options.radius_m of p_in_wg, or nullopt
/// where there are too few or they are not planar.
std::optional<LocalPlane> FitLocalPlane(const VoxelGrid& grid, const Eigen::Vector3d& p_in_wg,
                                        const LocalPlaneOptions& options = {});

}  // namespace ag
