#include "ground_server/voxel_map/voxel_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tuple>
#include <unordered_map>

#include "ground_server/voxel_map/voxel_hash_table.h"
#include "tests/support/option_error.h"

namespace ag {
namespace {

std::vector<Eigen::Vector3f> RandomCloud(std::mt19937& rng, int n, const Eigen::Vector3f& lo,
                                         const Eigen::Vector3f& hi) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Eigen::Vector3f> cloud;
  cloud.reserve(n);
  for (int i = 0; i < n; ++i) {
    cloud.emplace_back(lo.x() + (hi.x() - lo.x()) * u(rng), lo.y() + (hi.y() - lo.y()) * u(rng),
                       lo.z() + (hi.z() - lo.z()) * u(rng));
  }
  return cloud;
}

// Exhaustive nearest neighbour over `points`, optionally restricted by a
// predicate; same double arithmetic as the grid.
template <class Keep>
NearestResult BruteForce(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3d& q,
                         double max_distance, Keep keep) {
  NearestResult best;
  double best2 = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3f& p : points) {
    if (!keep(p)) continue;
    const double d2 = (p.cast<double>() - q).squaredNorm();
    if (d2 < best2) {
      best2 = d2;
      best.point = p;
    }
  }
  if (best2 <= max_distance * max_distance) {
    best.found = true;
    best.distance_m = std::sqrt(best2);
  }
  return best;
}

TEST(VoxelHashTableTest, MatchesStdUnorderedMapUnderInsertEraseChurn) {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> coord(-40, 40);
  internal::VoxelHashTable<uint32_t> table;
  std::unordered_map<uint64_t, uint32_t> reference;
  for (int op = 0; op < 200000; ++op) {
    const uint64_t key = internal::PackVoxelKey(coord(rng), coord(rng), coord(rng) / 8);
    const int what = op % 3;
    if (what == 0 || what == 1) {
      const auto [value, inserted] = table.Emplace(key, static_cast<uint32_t>(op));
      const auto [it, ref_inserted] = reference.emplace(key, static_cast<uint32_t>(op));
      ASSERT_EQ(inserted, ref_inserted);
      ASSERT_EQ(*value, it->second);
    } else {
      ASSERT_EQ(table.Erase(key), reference.erase(key) == 1);
    }
    if (op % 5000 == 0) {
      for (const auto& [k, v] : reference) {
        const uint32_t* found = table.Find(k);
        ASSERT_NE(found, nullptr);
        ASSERT_EQ(*found, v);
      }
    }
  }
  EXPECT_EQ(table.size(), reference.size());
  size_t visited = 0;
  table.ForEach([&](uint64_t k, uint32_t v) {
    ++visited;
    EXPECT_EQ(reference.at(k), v);
  });
  EXPECT_EQ(visited, reference.size());
  EXPECT_LE(2 * table.size(), table.capacity());
}

TEST(VoxelGridTest, NearestEqualsBruteForceWhenTheTrueNeighbourIsWithinOneVoxel) {
  std::mt19937 rng(2);
  VoxelGrid::Options options;
  options.max_points_per_voxel = 1000;  // keep every point: brute force sees the same cloud
  options.max_neighbor_distance_m = 1.0;
  VoxelGrid grid(options);
  const auto cloud = RandomCloud(rng, 20000, Eigen::Vector3f(-1.5f, -1.0f, -0.5f),
                                 Eigen::Vector3f(1.5f, 1.0f, 0.5f));
  const VoxelInsertStats stats = grid.Insert(cloud, Eigen::Vector3d::Zero());
  ASSERT_EQ(stats.points_added, cloud.size());
  ASSERT_EQ(grid.num_points(), cloud.size());

  const auto queries = RandomCloud(rng, 5000, Eigen::Vector3f(-1.7f, -1.2f, -0.7f),
                                   Eigen::Vector3f(1.7f, 1.2f, 0.7f));
  const auto all = [](const Eigen::Vector3f&) { return true; };
  int exact_cases = 0;
  for (const Eigen::Vector3f& qf : queries) {
    const Eigen::Vector3d q = qf.cast<double>();
    const NearestResult truth = BruteForce(cloud, q, 1e9, all);
    const NearestResult got = grid.Nearest(q, 27, 1.0);
    if (truth.distance_m < options.voxel_size_m) {
      // Any point closer than one voxel lies in the 27-neighbourhood.
      ++exact_cases;
      ASSERT_TRUE(got.found);
      EXPECT_EQ(got.point, truth.point);
      EXPECT_DOUBLE_EQ(got.distance_m, truth.distance_m);
    } else if (got.found) {
      EXPECT_GE(got.distance_m, truth.distance_m);
    }
  }
  EXPECT_GT(exact_cases, 3000);  // most queries lie inside the cloud
}

TEST(VoxelGridTest, NearestIsExactWithinTheSearchedNeighbourhoodAndRespectsMaxDistance) {
  std::mt19937 rng(3);
  VoxelGrid::Options options;
  options.max_points_per_voxel = 1000;
  VoxelGrid grid(options);
  // Sparse cloud so neighbourhoods are often partly empty.
  const auto cloud = RandomCloud(rng, 3000, Eigen::Vector3f(-1.5f, -1.5f, -1.5f),
                                 Eigen::Vector3f(1.5f, 1.5f, 1.5f));
  grid.Insert(cloud, Eigen::Vector3d::Zero());
  const auto queries = RandomCloud(rng, 3000, Eigen::Vector3f(-1.5f, -1.5f, -1.5f),
                                   Eigen::Vector3f(1.5f, 1.5f, 1.5f));
  for (int neighborhood : {7, 19, 27}) {
    for (double max_distance : {0.05, 0.12, 10.0}) {
      int found = 0;
      for (const Eigen::Vector3f& qf : queries) {
        const Eigen::Vector3d q = qf.cast<double>();
        const VoxelIndex vq = grid.VoxelOf(q);
        // Independent definition of the neighbourhoods: L1 distance of voxel
        // indices <= 1 (7), each |d| <= 1 and L1 <= 2 (19), each |d| <= 1 (27).
        const auto searched = [&](const Eigen::Vector3f& p) {
          const VoxelIndex d = grid.VoxelOf(p.cast<double>()) - vq;
          if (d.cwiseAbs().maxCoeff() > 1) return false;
          const int l1 = d.cwiseAbs().sum();
          return neighborhood == 27 || (neighborhood == 19 && l1 <= 2) || l1 <= 1;
        };
        const NearestResult truth = BruteForce(cloud, q, max_distance, searched);
        const NearestResult got = grid.Nearest(q, neighborhood, max_distance);
        ASSERT_EQ(got.found, truth.found) << neighborhood << " " << max_distance;
        if (truth.found) {
          ++found;
          EXPECT_EQ(got.point, truth.point);
          EXPECT_DOUBLE_EQ(got.distance_m, truth.distance_m);
          EXPECT_LE(got.distance_m, max_distance);
        }
      }
      if (max_distance > 1.0) {
        EXPECT_GT(found, 0);
      }
    }
  }
}

TEST(VoxelGridTest, KeepsAtMostMaxPointsPerVoxelAndRejectsBadPoints) {
  VoxelGrid::Options options;
  options.max_points_per_voxel = 3;
  ASSERT_FALSE(options.keep_latest);  // the default, as iVox
  VoxelGrid grid(options);
  std::vector<Eigen::Vector3f> points;
  points.reserve(12);
  for (int i = 0; i < 10; ++i) points.emplace_back(0.01f + 0.005f * i, 0.05f, 0.05f);
  points.emplace_back(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f);
  points.emplace_back(1e9f, 0.0f, 0.0f);  // beyond the eviction radius
  const VoxelInsertStats stats = grid.Insert(points, Eigen::Vector3d::Zero());
  EXPECT_EQ(stats.points_added, 3u);
  EXPECT_EQ(stats.points_voxel_full, 7u);
  EXPECT_EQ(stats.points_rejected, 1u);
  EXPECT_EQ(stats.points_beyond_radius, 1u);
  EXPECT_EQ(grid.num_voxels(), 1u);
  EXPECT_TRUE(grid.IsOccupied(VoxelIndex(0, 0, 0)));
  EXPECT_FALSE(grid.IsOccupied(VoxelIndex(1, 0, 0)));
  // iVox keeps the first points of a voxel.
  const auto kept = grid.PointsInVoxel(VoxelIndex(0, 0, 0));
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[2], points[2]);

  // Without a radius, points beyond the key range are rejected, not wrapped.
  options.eviction_radius_m = 0;
  VoxelGrid unbounded(options);
  const VoxelInsertStats far =
      unbounded.Insert({Eigen::Vector3f(2e5f, 0, 0)}, Eigen::Vector3d::Zero());
  EXPECT_EQ(far.points_rejected, 1u);
  EXPECT_EQ(unbounded.num_voxels(), 0u);
  EXPECT_FALSE(unbounded.Nearest(Eigen::Vector3d(2e5, 0, 0)).found);
}

// A "scan": a patch of n x n voxels, one point each, at height z.
std::vector<Eigen::Vector3f> Patch(float x0, float y0, float z, int n) {
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j)
      points.emplace_back(x0 + 0.1f * i + 0.05f, y0 + 0.1f * j + 0.05f, z);
  }
  return points;
}

TEST(VoxelGridTest, KeepLatestReplacesAFullVoxelsOldestPoints) {
  VoxelGrid::Options options;
  options.max_points_per_voxel = 3;
  options.keep_latest = true;
  VoxelGrid grid(options);
  const auto at = [](int i) { return Eigen::Vector3f(0.01f + 0.008f * i, 0.05f, 0.05f); };
  std::vector<Eigen::Vector3f> first;
  first.reserve(5);
  for (int i = 0; i < 5; ++i) first.push_back(at(i));
  VoxelInsertStats stats = grid.Insert(first, Eigen::Vector3d::Zero());
  EXPECT_EQ(stats.points_added, 3u);
  EXPECT_EQ(stats.points_replaced, 2u);
  EXPECT_EQ(stats.points_voxel_full, 0u);
  EXPECT_EQ(grid.num_points(), 3u);
  const auto sorted_x = [&grid] {
    std::vector<float> x;
    for (const Eigen::Vector3f& p : grid.PointsInVoxel(VoxelIndex(0, 0, 0))) x.push_back(p.x());
    std::sort(x.begin(), x.end());
    return x;
  };
  EXPECT_EQ(sorted_x(), (std::vector<float>{at(2).x(), at(3).x(), at(4).x()}));
  // The next scan goes on replacing in arrival order, across scans.
  stats = grid.Insert({at(5), at(6)}, Eigen::Vector3d::Zero());
  EXPECT_EQ(stats.points_replaced, 2u);
  EXPECT_EQ(grid.num_points(), 3u);
  EXPECT_EQ(sorted_x(), (std::vector<float>{at(4).x(), at(5).x(), at(6).x()}));
  // A query near the first points now finds the newest point nearest to it.
  const NearestResult r = grid.Nearest(at(0).cast<double>());
  ASSERT_TRUE(r.found);
  EXPECT_EQ(r.point, at(4));
}

TEST(VoxelGridTest, CapEvictionKeepsTheCountBoundedAndDropsTheLeastRecentlyUpdated) {
  VoxelGrid::Options options;
  options.max_voxels = 1000;
  options.eviction_radius_m = 0;
  VoxelGrid grid(options);
  // Patch 0 is refreshed by every scan; each scan also adds 400 new voxels.
  const auto keep_alive = Patch(-5.0f, -5.0f, 0.05f, 5);
  size_t evicted = 0;
  for (int scan = 0; scan < 12; ++scan) {
    auto points = Patch(0.0f, 0.0f, 0.05f + 0.1f * scan, 20);
    points.insert(points.end(), keep_alive.begin(), keep_alive.end());
    const VoxelInsertStats stats = grid.Insert(points, Eigen::Vector3d::Zero());
    evicted += stats.voxels_evicted_cap;
    ASSERT_LE(grid.num_voxels(), 1000u) << "scan " << scan;
    // The newest scan and the refreshed patch always survive.
    for (const Eigen::Vector3f& p : points)
      ASSERT_TRUE(grid.IsOccupied(grid.VoxelOf(p.cast<double>())));
  }
  EXPECT_GT(evicted, 0u);
  // The oldest layers are gone.
  EXPECT_FALSE(grid.IsOccupied(grid.VoxelOf(Eigen::Vector3d(0.05, 0.05, 0.05))));
  EXPECT_EQ(grid.num_points(), grid.Points().size());
  // Every voxel of a patch got one point per scan; the refreshed one more.
  EXPECT_EQ(grid.num_points(), grid.num_voxels() - 25 + 25 * 10);
}

TEST(VoxelGridTest, RadiusEvictionRemovesVoxelsFarFromTheSensor) {
  VoxelGrid::Options options;
  options.eviction_radius_m = 10.0;
  VoxelGrid grid(options);
  grid.Insert(Patch(0.0f, 0.0f, 0.05f, 10), Eigen::Vector3d::Zero());
  grid.Insert(Patch(9.0f, 0.0f, 0.05f, 10), Eigen::Vector3d(9.0, 0, 0));
  EXPECT_EQ(grid.num_voxels(), 200u);
  // Moving to x = 15 puts the first patch (x <= 1) beyond 10 m.
  const VoxelInsertStats stats =
      grid.Insert(Patch(15.0f, 0.0f, 0.05f, 10), Eigen::Vector3d(15, 0, 0));
  EXPECT_EQ(stats.voxels_evicted_radius, 100u);
  EXPECT_EQ(grid.num_voxels(), 200u);
  EXPECT_FALSE(grid.IsOccupied(grid.VoxelOf(Eigen::Vector3d(0.05, 0.05, 0.05))));
  EXPECT_TRUE(grid.IsOccupied(grid.VoxelOf(Eigen::Vector3d(9.05, 0.05, 0.05))));
}

// True when some occupied voxel's 3x3x3 neighbourhood touches the block of
// voxels [first, first + edge - 1]^3 (brute force over all occupied voxels).
bool BlockTouched(const std::set<std::tuple<int, int, int>>& occupied, const VoxelIndex& first,
                  int edge) {
  const VoxelIndex last = first + VoxelIndex::Constant(edge - 1);
  for (const auto& [x, y, z] : occupied) {
    const VoxelIndex v(x, y, z);
    if ((v.array() + 1 >= first.array()).all() && (v.array() - 1 <= last.array()).all()) {
      return true;
    }
  }
  return false;
}

int FloorDivTest(int a, int b) { return static_cast<int>(std::floor(static_cast<double>(a) / b)); }

// EmptyBlockAt equals its definition, recomputed from the occupied voxels:
// the coarse block if untouched, else the fine block if untouched, else none.
void ExpectEmptyBlocksMatchDefinition(const VoxelGrid& grid, std::mt19937& rng) {
  std::set<std::tuple<int, int, int>> occupied;
  for (const Eigen::Vector3f& p : grid.Points()) {
    const VoxelIndex v = grid.VoxelOf(p.cast<double>());
    occupied.emplace(v.x(), v.y(), v.z());
  }
  const int coarse = grid.options().skip_block_voxels;
  const int fine = coarse / 4;
  std::uniform_int_distribution<int> coord(-30, 30);
  int coarse_empty = 0, fine_empty = 0, not_empty = 0;
  for (int trial = 0; trial < 1500; ++trial) {
    const VoxelIndex v(coord(rng), coord(rng), coord(rng) / 4);
    VoxelIndex coarse_first, fine_first;
    for (int a = 0; a < 3; ++a) {
      coarse_first[a] = FloorDivTest(v[a], coarse) * coarse;
      fine_first[a] = FloorDivTest(v[a], fine) * fine;
    }
    const VoxelGrid::EmptyBlock got = grid.EmptyBlockAt(v);
    if (!BlockTouched(occupied, coarse_first, coarse)) {
      ++coarse_empty;
      ASSERT_EQ(got.edge_voxels, coarse) << v.transpose();
      ASSERT_EQ(got.first, coarse_first);
    } else if (!BlockTouched(occupied, fine_first, fine)) {
      ++fine_empty;
      ASSERT_EQ(got.edge_voxels, fine) << v.transpose();
      ASSERT_EQ(got.first, fine_first);
    } else {
      ++not_empty;
      ASSERT_EQ(got.edge_voxels, 0) << v.transpose();
    }
  }
  EXPECT_GT(coarse_empty, 0);
  EXPECT_GT(fine_empty, 0);
  EXPECT_GT(not_empty, 0);
}

TEST(VoxelGridTest, EmptyBlocksMatchTheirDefinitionThroughInsertAndEviction) {
  for (int skip : {8, 4, 16}) {
    std::mt19937 rng(4);
    VoxelGrid::Options options;
    options.skip_block_voxels = skip;
    options.max_voxels = 3000;
    options.eviction_radius_m = 0;
    VoxelGrid grid(options);
    for (int scan = 0; scan < 6; ++scan) {
      const float x0 = -2.5f + 0.3f * scan;
      grid.Insert(RandomCloud(rng, 1500, Eigen::Vector3f(x0, -2.5f, -0.6f),
                              Eigen::Vector3f(x0 + 2.0f, 2.5f, 0.6f)),
                  Eigen::Vector3d::Zero());
    }
    ASSERT_LE(grid.num_voxels(), 3000u);
    ExpectEmptyBlocksMatchDefinition(grid, rng);  // after cap evictions

    // Any successful query comes from a voxel not reported empty.
    const auto queries =
        RandomCloud(rng, 3000, Eigen::Vector3f(-3, -3, -1), Eigen::Vector3f(3, 3, 1));
    for (const Eigen::Vector3f& q : queries) {
      if (!grid.Nearest(q.cast<double>(), 27, 1.0).found) continue;
      ASSERT_EQ(grid.EmptyBlockAt(grid.VoxelOf(q.cast<double>())).edge_voxels, 0);
    }
    VoxelIndex lo, hi;
    ASSERT_TRUE(grid.OccupiedBounds(&lo, &hi));
    for (const Eigen::Vector3f& p : grid.Points()) {
      const VoxelIndex v = grid.VoxelOf(p.cast<double>());
      ASSERT_TRUE((v.array() >= lo.array()).all() && (v.array() <= hi.array()).all());
    }

    grid.Clear();
    EXPECT_EQ(grid.num_voxels(), 0u);
    EXPECT_FALSE(grid.OccupiedBounds(&lo, &hi));
    EXPECT_EQ(grid.EmptyBlockAt(VoxelIndex::Zero()).edge_voxels, skip);
  }
  VoxelGrid::Options off;
  off.skip_block_voxels = 0;
  EXPECT_EQ(VoxelGrid(off).EmptyBlockAt(VoxelIndex::Zero()).edge_voxels, 0);
}

TEST(VoxelGridTest, OptionsCheckNamesTheField) {
  VoxelGrid::Options options;
  options.neighborhood = 9;
  test::ExpectOptionErrorNaming("neighborhood", [&] { VoxelGrid grid(options); });
  options = VoxelGrid::Options();
  options.voxel_size_m = 0;
  EXPECT_THROW(VoxelGrid{options}, OptionError);
}

}  // namespace
}  // namespace ag
