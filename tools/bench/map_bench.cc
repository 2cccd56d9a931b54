// map_bench: timing of the ground perception (voxel map, depth association)
// on a simulated street: a 64-beam spinning LiDAR driving along it fills the
// map, then a camera keyframe at the last pose asks for the depth of 1024
// keypoints. Prints tables; nothing is asserted (tests check correctness).
//
//   map_bench [--scans 10] [--keypoints 1024] [--repeats 5]

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <random>
#include <thread>
#include <unordered_map>
#include <vector>

#include "common/camera/camera.h"
#include "common/core/cpu_time.h"
#include "ground_server/depth/depth_association.h"
#include "ground_server/voxel_map/voxel_grid.h"
#include "ground_server/voxel_map/voxel_hash_table.h"
#include "ground_server/voxel_map/voxel_map.h"

namespace ag {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// Axis-aligned boxes; the street is the ground slab, two facades and cars,
// poles and kerbs along it.
struct Box {
  Eigen::Vector3d lo, hi;
};

class Street {
 public:
  explicit Street(std::mt19937* rng) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    boxes_.push_back({{-50, -30, -1}, {250, 30, 0}});   // ground
    boxes_.push_back({{-50, 9, 0}, {250, 10, 15}});     // facade left
    boxes_.push_back({{-50, -10, 0}, {250, -9, 12}});   // facade right
    boxes_.push_back({{-50, 6, 0}, {250, 6.2, 0.15}});  // kerbs
    boxes_.push_back({{-50, -6.2, 0}, {250, -6, 0.15}});
    for (double x = -40; x < 240; x += 6 + 8 * u(*rng)) {  // parked cars
      const double y = u(*rng) < 0.5 ? 4.0 : -6.0;
      boxes_.push_back({{x, y, 0}, {x + 4.2, y + 1.8, 1.5}});
    }
    for (double x = -40; x < 240; x += 15) {  // poles
      boxes_.push_back({{x, 7, 0}, {x + 0.2, 7.2, 5}});
      boxes_.push_back({{x + 7, -7.2, 0}, {x + 7.2, -7, 5}});
    }
  }

  /// Distance along the ray to the first box, or infinity.
  double Cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_range) const {
    double best = max_range;
    bool hit = false;
    for (const Box& b : boxes_) {
      double t0 = 0, t1 = best;
      bool miss = false;
      for (int a = 0; a < 3 && !miss; ++a) {
        if (std::abs(d[a]) < 1e-12) {
          miss = o[a] < b.lo[a] || o[a] > b.hi[a];
          continue;
        }
        double ta = (b.lo[a] - o[a]) / d[a];
        double tb = (b.hi[a] - o[a]) / d[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        miss = t0 > t1;
      }
      if (!miss && t0 > 1e-6 && t0 < best) {
        best = t0;
        hit = true;
      }
    }
    return hit ? best : std::numeric_limits<double>::infinity();
  }

 private:
  std::vector<Box> boxes_;
};

// One spinning-LiDAR scan (HDL-64-like: 64 beams over +2..-24.8 deg, 0.2 deg
// azimuth steps, 100 m range, 1 cm noise) from the sensor at `position`.
std::vector<Eigen::Vector3f> SimulateScan(const Street& street, const Eigen::Vector3d& position,
                                          std::mt19937* rng) {
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<Eigen::Vector3f> points;
  for (int beam = 0; beam < 64; ++beam) {
    const double elevation = (2.0 - 26.8 * beam / 63.0) * M_PI / 180.0;
    for (int step = 0; step < 1800; ++step) {
      const double azimuth = step * 0.2 * M_PI / 180.0;
      const Eigen::Vector3d d(std::cos(elevation) * std::cos(azimuth),
                              std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
      const double t = street.Cast(position, d, 100.0);
      if (std::isfinite(t)) points.push_back((position + (t + noise(*rng)) * d).cast<float>());
    }
  }
  return points;
}

Pose ForwardCamera(const Eigen::Vector3d& position) {
  Eigen::Matrix3d base;  // camera x right = -y, y down = -z, z forward = +x
  base << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()).toRotationMatrix() * base;
  T.translation() = position;
  return T;
}

// Best of `repeats` runs, in thread CPU time, or wall time when `wall`
// (where waiting on a lock is part of the cost).
template <class Fn>
double BestMs(int repeats, Fn&& fn, bool wall = false) {
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r < repeats; ++r) {
    const auto start = Clock::now();
    const double cpu_start = ThreadCpuMs();
    fn();
    best = std::min(best, wall ? MsSince(start) : ThreadCpuMs() - cpu_start);
  }
  return best;
}

bool SameAnswers(const DepthAssociationResult& a, const DepthAssociationResult& b) {
  if (a.keypoints.size() != b.keypoints.size()) return false;
  for (size_t i = 0; i < a.keypoints.size(); ++i) {
    if (a.keypoints[i].valid != b.keypoints[i].valid) return false;
    if (a.keypoints[i].valid && a.keypoints[i].p_in_wg != b.keypoints[i].p_in_wg) return false;
  }
  return true;
}

int Run(int num_scans, int num_keypoints, int repeats) {
  std::mt19937 rng(7);
  const Street street(&rng);
  std::vector<std::vector<Eigen::Vector3f>> scans;
  std::vector<Eigen::Vector3d> positions;
  size_t total_points = 0;
  for (int k = 0; k < num_scans; ++k) {
    positions.emplace_back(2.0 * k, 0.5, 1.8);
    scans.push_back(SimulateScan(street, positions.back(), &rng));
    total_points += scans.back().size();
  }
  std::printf(
      "map_bench: %d simulated scans (%.0f points each); times are thread CPU time, best "
      "of %d, except where marked wall\n\n",
      num_scans, static_cast<double>(total_points) / num_scans, repeats);

  // --- insertion ---
  VoxelGrid::Options grid_options;
  VoxelGrid grid(grid_options);
  double insert_ms = 0;
  for (int k = 0; k < num_scans; ++k) {
    const double start = ThreadCpuMs();
    grid.Insert(scans[k], positions[k]);
    insert_ms += ThreadCpuMs() - start;
  }
  VoxelMap locked_map;
  const double locked_start = ThreadCpuMs();
  for (int k = 0; k < num_scans; ++k) locked_map.Insert(scans[k], positions[k]);
  const double locked_ms = ThreadCpuMs() - locked_start;
  VoxelGrid::Options no_skip_options;
  no_skip_options.skip_block_voxels = 0;
  VoxelGrid no_skip(no_skip_options);
  const double no_skip_start = ThreadCpuMs();
  for (int k = 0; k < num_scans; ++k) no_skip.Insert(scans[k], positions[k]);
  const double no_skip_ms = ThreadCpuMs() - no_skip_start;
  std::printf("| insertion | ms / scan | Mpoints / s |\n|---|---|---|\n");
  std::printf("| VoxelGrid, skip blocks 8 / 2 | %.1f | %.2f |\n", insert_ms / num_scans,
              total_points / insert_ms / 1e3);
  std::printf("| VoxelGrid, no skip blocks | %.1f | %.2f |\n", no_skip_ms / num_scans,
              total_points / no_skip_ms / 1e3);
  std::printf("| VoxelMap (locked, chunks of %d) | %.1f | %.2f |\n",
              locked_map.options().insert_chunk_points, locked_ms / num_scans,
              total_points / locked_ms / 1e3);
  std::printf("\nmap: %zu voxels, %zu points, %.1f MB\n\n", grid.num_voxels(), grid.num_points(),
              grid.MemoryBytes() / 1e6);

  // --- nearest neighbour ---
  std::vector<Eigen::Vector3d> near_queries, far_queries;
  {
    const auto all = grid.Points();
    std::uniform_int_distribution<size_t> pick(0, all.size() - 1);
    std::normal_distribution<double> noise(0.0, 0.05);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < 200000; ++i) {
      near_queries.push_back(all[pick(rng)].cast<double>() +
                             Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
      far_queries.emplace_back(2.0 * num_scans * u(rng), -8 + 16 * u(rng), 3 + 5 * u(rng));
    }
  }
  std::printf(
      "| nearest neighbour (ns / query) | near surfaces | in free space |\n|---|---|---|\n");
  for (int neighborhood : {7, 19, 27}) {
    size_t found = 0;
    const double near_ms = BestMs(repeats, [&] {
      for (const auto& q : near_queries) found += grid.Nearest(q, neighborhood, 0.2).found;
    });
    const double far_ms = BestMs(repeats, [&] {
      for (const auto& q : far_queries) found += grid.Nearest(q, neighborhood, 0.2).found;
    });
    std::printf("| %d voxels | %.0f | %.0f |\n", neighborhood, near_ms * 1e6 / near_queries.size(),
                far_ms * 1e6 / far_queries.size());
  }

  // --- open addressing vs std::unordered_map for the voxel lookups ---
  {
    std::vector<uint64_t> keys;
    for (const auto& p : grid.Points()) {
      const VoxelIndex v = grid.VoxelOf(p.cast<double>());
      keys.push_back(internal::PackVoxelKey(v.x(), v.y(), v.z()));
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    internal::VoxelHashTable<uint32_t> open;
    std::unordered_map<uint64_t, uint32_t> node;
    node.reserve(keys.size());
    for (size_t i = 0; i < keys.size(); ++i) {
      open.Emplace(keys[i], static_cast<uint32_t>(i));
      node.emplace(keys[i], static_cast<uint32_t>(i));
    }
    std::vector<uint64_t> probes;  // the 27-neighbourhoods of near queries: hits and misses
    for (size_t i = 0; i < 20000; ++i) {
      const VoxelIndex v = grid.VoxelOf(near_queries[i]);
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dz = -1; dz <= 1; ++dz) {
            probes.push_back(internal::PackVoxelKey(v.x() + dx, v.y() + dy, v.z() + dz));
          }
        }
      }
    }
    uint64_t sink = 0;
    const double open_ms = BestMs(repeats, [&] {
      for (uint64_t k : probes) {
        const uint32_t* v = open.Find(k);
        sink += v != nullptr ? *v : 0;
      }
    });
    const double node_ms = BestMs(repeats, [&] {
      for (uint64_t k : probes) {
        const auto it = node.find(k);
        sink += it != node.end() ? it->second : 0;
      }
    });
    std::printf("\n| voxel lookup (%zu keys) | ns / probe |\n|---|---|\n", keys.size());
    std::printf("| open addressing (VoxelHashTable) | %.1f |\n", open_ms * 1e6 / probes.size());
    std::printf("| std::unordered_map | %.1f |\n", node_ms * 1e6 / probes.size());
    if (sink == 42) std::printf(" ");
  }

  // --- depth association per keyframe ---
  CameraParams params;  // a 720p UGV camera (Azure Kinect-like)
  params.width = 1280;
  params.height = 720;
  params.fx = params.fy = 640;
  params.cx = 639.5;
  params.cy = 359.5;
  const Camera camera(params);
  const Pose T_wg_c = ForwardCamera(positions.back() + Eigen::Vector3d(0.3, 0.0, 0.2));
  std::vector<Eigen::Vector2f> keypoints;
  {
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int i = 0; i < num_keypoints; ++i) {
      keypoints.emplace_back(u(rng) * (params.width - 1), u(rng) * (params.height - 1));
    }
  }
  DepthAssociator::Options options;
  const DepthAssociator associator(camera, options);
  DepthAssociationResult ref, fast;
  const double ref_ms = BestMs(std::max(1, repeats / 2), [&] {
    ref = associator.AssociateReference(grid, T_wg_c, keypoints);
  });
  const double fast_ms =
      BestMs(repeats, [&] { fast = associator.Associate(grid, T_wg_c, keypoints); });
  std::printf(
      "\ndepth association, %d keypoints (uniform pixels, %.0f%% given depth), range "
      "%.1f-%.0f m, step %.2f m:\n",
      num_keypoints, 100.0 * fast.fraction_valid(), options.min_range_m, options.max_range_m,
      options.step_m);
  std::printf(
      "| march | ms / keyframe | samples queried | samples skipped | block checks | "
      "same answers |\n|---|---|---|---|---|---|\n");
  std::printf("| reference (fixed step) | %.2f | %zu | 0 | 0 | - |\n", ref_ms, ref.samples_queried);
  std::printf("| skipping, blocks 8 / 2 voxels | %.2f | %zu | %zu | %zu | %s |\n", fast_ms,
              fast.samples_queried, fast.samples_skipped, fast.skip_checks,
              SameAnswers(fast, ref) ? "yes" : "NO");
  for (int skip : {0, 4, 16, 32}) {
    VoxelGrid::Options skip_options;
    skip_options.skip_block_voxels = skip;
    VoxelGrid variant(skip_options);
    for (int k = 0; k < num_scans; ++k) variant.Insert(scans[k], positions[k]);
    DepthAssociationResult r;
    const double ms =
        BestMs(repeats, [&] { r = associator.Associate(variant, T_wg_c, keypoints); });
    std::printf("| skipping, blocks %d / %d voxels | %.2f | %zu | %zu | %zu | %s |\n", skip,
                skip / 4, ms, r.samples_queried, r.samples_skipped, r.skip_checks,
                SameAnswers(r, ref) ? "yes" : "NO");
  }

  // --- queries while another thread inserts ---
  {
    VoxelMap map;
    for (int k = 0; k + 1 < num_scans; ++k) map.Insert(scans[k], positions[k]);
    auto keyframe = [&] {
      const VoxelMap::Reader reader = map.Read();
      return associator.Associate(reader.grid(), T_wg_c, keypoints).num_valid;
    };
    const double idle_ms = BestMs(repeats, keyframe, /*wall=*/true);
    std::atomic<bool> stop{false};
    std::atomic<int> inserted{0};
    std::thread writer([&] {
      while (!stop) {
        map.Insert(scans[num_scans - 1], positions[num_scans - 1]);
        ++inserted;
      }
    });
    const double busy_ms = BestMs(repeats, keyframe, /*wall=*/true);
    // Fewer single queries while inserting: each waits for the chunk in
    // progress (up to ~2 ms).
    constexpr size_t kBusyQueries = 2000, kIdleQueries = 50000;
    size_t found = 0;
    const auto single_start = Clock::now();
    for (size_t i = 0; i < kBusyQueries; ++i) found += map.Nearest(near_queries[i]).found;
    const double single_ns = MsSince(single_start) * 1e6 / kBusyQueries;
    stop = true;
    writer.join();
    const auto idle_single_start = Clock::now();
    for (size_t i = 0; i < kIdleQueries; ++i) found += map.Nearest(near_queries[i]).found;
    const double idle_single_ns = MsSince(idle_single_start) * 1e6 / kIdleQueries;
    std::printf(
        "\n| VoxelMap under a concurrent inserter (wall time) | idle | inserting |\n"
        "|---|---|---|\n");
    std::printf("| keyframe (one Reader), ms | %.2f | %.2f |\n", idle_ms, busy_ms);
    std::printf("| Nearest() with its own lock, ns | %.0f | %.0f |\n", idle_single_ns, single_ns);
    std::printf("(%d scans inserted meanwhile; 2 cores shared by both threads)\n", inserted.load());
  }
  return 0;
}

}  // namespace
}  // namespace ag

int main(int argc, char** argv) {
  CLI::App app{"Timing of the voxel map and the keypoint depth association"};
  int scans = 10;
  int keypoints = 1024;
  int repeats = 5;
  app.add_option("--scans", scans, "simulated LiDAR scans in the map")->check(CLI::Range(2, 1000));
  app.add_option("--keypoints", keypoints, "keypoints per keyframe")->check(CLI::Range(1, 100000));
  app.add_option("--repeats", repeats, "timing repetitions (best is reported)")
      ->check(CLI::Range(1, 100));  // best of
  CLI11_PARSE(app, argc, argv);
  try {
    return ag::Run(scans, keypoints, repeats);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "map_bench: %s\n", e.what());
    return 1;
  }
}
