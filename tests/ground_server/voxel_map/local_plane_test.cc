// FitLocalPlane: the map's surface at a point, only where it is flat.
#include "ground_server/voxel_map/local_plane.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

namespace ag {
namespace {

VoxelGrid Grid(const std::vector<Eigen::Vector3f>& points) {
  VoxelGrid::Options o;
  o.max_points_per_voxel = 50;
  VoxelGrid grid(o);
  grid.Insert(points, Eigen::Vector3d::Zero());
  return grid;
}

TEST(LocalPlaneTest, FitsATiltedNoisyPlane) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  std::normal_distribution<float> n(0, 0.005f);
  const Eigen::Vector3f normal = Eigen::Vector3f(0.2f, -0.3f, 1.0f).normalized();
  const Eigen::Vector3f a = normal.unitOrthogonal();
  const Eigen::Vector3f b = normal.cross(a);
  std::vector<Eigen::Vector3f> points;
  points.reserve(4000);
  for (int i = 0; i < 4000; ++i) points.push_back(u(rng) * a + u(rng) * b + n(rng) * normal);
  const auto plane = FitLocalPlane(Grid(points), Eigen::Vector3d(0.1, 0.1, 0.0));
  ASSERT_TRUE(plane.has_value());
  EXPECT_GT(std::abs(plane->normal.dot(normal.cast<double>())), 0.995);
  EXPECT_NEAR(plane->rms_m, 0.005, 0.002);
  EXPECT_LT(std::abs(normal.cast<double>().dot(plane->point)), 0.003);
}

TEST(LocalPlaneTest, RejectsEdgesLinesAndEmptySpace) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<Eigen::Vector3f> corner, line;
  for (int i = 0; i < 3000; ++i) {
    corner.emplace_back(u(rng) - 0.5f, u(rng) - 0.5f, 0.0f);  // floor
    corner.emplace_back(0.0f, u(rng) - 0.5f, u(rng));         // wall at x = 0
    line.emplace_back(u(rng) - 0.5f, 0.0f, 0.0f);             // one LiDAR ring
  }
  EXPECT_FALSE(FitLocalPlane(Grid(corner), Eigen::Vector3d(0, 0, 0)).has_value());
  EXPECT_FALSE(FitLocalPlane(Grid(line), Eigen::Vector3d(0, 0, 0)).has_value());
  EXPECT_FALSE(FitLocalPlane(Grid(line), Eigen::Vector3d(0, 5, 0)).has_value());
  // Away from the corner the floor is a plane again.
  const auto floor = FitLocalPlane(Grid(corner), Eigen::Vector3d(-0.35, 0.0, 0.0));
  ASSERT_TRUE(floor.has_value());
  EXPECT_GT(std::abs(floor->normal.z()), 0.999);
}

}  // namespace
}  // namespace ag
