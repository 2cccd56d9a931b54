#include "ground_server/voxel_map/local_plane.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <vector>

namespace ag {

void LocalPlaneOptions::Check() const {
  CheckOption(radius_m > 0 && radius_m <= 2.0, "radius_m", "must be in (0, 2] m");
  CheckOption(min_points >= 3, "min_points", "must be >= 3");
  CheckOption(max_rms_m > 0, "max_rms_m", "must be > 0");
  CheckOption(min_extent_ratio >= 0 && min_extent_ratio <= 1, "min_extent_ratio",
              "must be in [0, 1]");
}

std::optional<LocalPlane> FitLocalPlane(const VoxelGrid& grid, const Eigen::Vector3d& p_in_wg,
                                        const LocalPlaneOptions& options) {
  const double voxel = grid.options().voxel_size_m;
  const int reach = static_cast<int>(std::ceil(options.radius_m / voxel));
  const VoxelIndex centre = grid.VoxelOf(p_in_wg);
  const double r2 = options.radius_m * options.radius_m;
  std::vector<Eigen::Vector3d> points;
  for (int dx = -reach; dx <= reach; ++dx) {
    for (int dy = -reach; dy <= reach; ++dy) {
      for (int dz = -reach; dz <= reach; ++dz) {
        for (const Eigen::Vector3f& q : grid.PointsInVoxel(centre + VoxelIndex(dx, dy, dz))) {
          const Eigen::Vector3d qd = q.cast<double>();
          if ((qd - p_in_wg).squaredNorm() <= r2) points.push_back(qd);
        }
      }
    }
  }
  if (static_cast<int>(points.size()) < options.min_points) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& q : points) mean += q;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& q : points) cov += (q - mean) * (q - mean).transpose();
  cov /= static_cast<double>(points.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);  // ascending eigenvalues
  const Eigen::Vector3d lambda = eig.eigenvalues().cwiseMax(0.0);
  if (lambda(1) < options.min_extent_ratio * options.min_extent_ratio * lambda(2)) {
    return std::nullopt;
  }
  LocalPlane plane;
  plane.rms_m = std::sqrt(lambda(0));
  if (plane.rms_m > options.max_rms_m) return std::nullopt;
  plane.point = mean;
  plane.normal = eig.eigenvectors().col(0).normalized();
  plane.num_points = static_cast<int>(points.size());
  return plane;
}

}  // namespace ag
