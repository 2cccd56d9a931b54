#pragma once

// Sparse voxel hash map of LiDAR points in the ground (LIO) world.
//
// Paper, "Pixel-Point Correspondence": following iVox (Faster-LIO), voxels
// exist only where points are, found through a hash table keyed by the
// integer voxel coordinates; voxel size 0.1 m. Each voxel keeps up to
// max_points_per_voxel points (iVox ignores later ones; with keep_latest a
// full voxel replaces its oldest point instead); the nearest neighbour of a
// query point is searched over its voxel and the 6 / 18 / 26 neighbouring
// ones.
//
// Memory is bounded by two eviction rules, both applied at the end of each
// inserted scan:
//  1. radius: points farther than eviction_radius_m from the scan's sensor
//     position are not inserted, and voxels whose centre is farther than the
//     radius from the latest sensor position are removed. The O(voxels) sweep
//     runs when the sensor has moved more than 5% of the radius since the last
//     sweep, so a voxel may outlive the radius by at most that much.
//  2. cap: when more than max_voxels voxels exist, the least recently updated
//     ones (the scan counter of the last point that fell in the voxel; ties
//     broken by slot order) are evicted down to 90% of max_voxels. The 10%
//     hysteresis makes the O(voxels) selection run once per many scans instead
//     of after every scan at the cap. Within one scan the count may exceed
//     the cap until that scan's end.
//
// Empty-space skipping (for ray marching in ground_server/depth): space is
// tiled by coarse blocks of skip_block_voxels^3 voxels, each split into 4^3
// fine blocks. A fine block is "empty" when no occupied voxel has its 3x3x3
// neighbourhood touching it: then no point inside it has a map point in its
// 27-neighbourhood, so every nearest-neighbour query from inside it fails.
// The grid counts, per fine block, the occupied voxels whose neighbourhood
// touches it (insert / evict side only), and keeps per coarse block a 64-bit
// mask of its non-empty fine blocks, so EmptyBlockAt() is one probe into a
// small table.
//
// Not thread-safe; ag::VoxelMap adds the locking.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "common/core/error.h"
#include "ground_server/voxel_map/voxel_hash_table.h"

namespace ag {

/// Integer voxel (or block) coordinates.
using VoxelIndex = Eigen::Vector3i;

/// The nearest map point of a query, if any within the searched voxels.
struct NearestResult {
  bool found = false;
  Eigen::Vector3f point = Eigen::Vector3f::Zero();  ///< the map point (world frame)
  double distance_m = 0.0;                          ///< distance to the query (m)
};

/// What one inserted scan did to the grid.
struct VoxelInsertStats {
  size_t points_added = 0;          ///< stored in a voxel
  size_t points_voxel_full = 0;     ///< fell in a full voxel and were ignored
  size_t points_replaced = 0;       ///< replaced a full voxel's oldest point (keep_latest)
  size_t points_rejected = 0;       ///< non-finite or outside the key range (+-104 km at 0.1 m)
  size_t points_beyond_radius = 0;  ///< farther than eviction_radius_m from the sensor
  size_t voxels_created = 0;
  size_t voxels_evicted_radius = 0;
  size_t voxels_evicted_cap = 0;

  void Accumulate(const VoxelInsertStats& other);
};

class VoxelGrid {
 public:
  struct Options {
    double voxel_size_m = 0.1;      ///< voxel edge (m); paper: 0.1
    int max_points_per_voxel = 10;  ///< points kept per voxel; later ones are ignored (iVox)
    /// A full voxel replaces its oldest point with a new one instead of
    /// ignoring it, so the map holds what the LiDAR saw last. Odometry
    /// drifts: the points a voxel got first, often from far away and long
    /// ago, sit where the odometry of that time put them, and the map near
    /// the vehicle then disagrees with its current pose by the drift since.
    /// Off by default: over 10 simulated seeds it helped `covisible` but not
    /// `no_initial_covisibility` (tools/evaluation/ACCURACY.md).
    bool keep_latest = false;
    /// Voxel-count cap (LRU eviction). Memory is ~240 bytes per voxel with
    /// 10 points per voxel (map_bench), so ~120 MB at the default cap.
    int max_voxels = 500000;
    double eviction_radius_m = 100.0;  ///< voxels farther from the sensor are dropped (m); 0 = off
    int neighborhood = 27;             ///< nearest-neighbour search: 7, 19 or 27 voxels
    double max_neighbor_distance_m =
        0.1;  ///< neighbours farther are not returned (m); 1 voxel: exact
    /// Edge of the coarse empty-space blocks (voxels), a multiple of 4 (fine
    /// blocks are a quarter of it); 0 disables. A new voxel updates the
    /// counters of the (edge/4 == 1 ? 27 : 8) fine blocks its neighbourhood touches.
    int skip_block_voxels = 8;

    template <class V>
    void VisitFields(V& v) {
      v("voxel_size_m", voxel_size_m);
      v("max_points_per_voxel", max_points_per_voxel);
      v("keep_latest", keep_latest);
      v("max_voxels", max_voxels);
      v("eviction_radius_m", eviction_radius_m);
      v("neighborhood", neighborhood);
      v("max_neighbor_distance_m", max_neighbor_distance_m);
      v("skip_block_voxels", skip_block_voxels);
    }
    void Check() const;
  };

  VoxelGrid();
  /// Throws ag::OptionError if `options` are invalid.
  explicit VoxelGrid(const Options& options);

  const Options& options() const { return options_; }

  /// Inserts a scan already transformed into the world; `sensor_in_wg` is
  /// where it was taken from (for radius eviction). Same as BeginScan +
  /// AddPoints + EndScan.
  VoxelInsertStats Insert(const std::vector<Eigen::Vector3f>& points_in_wg,
                          const Eigen::Vector3d& sensor_in_wg);

  /// A scan in pieces, so ag::VoxelMap can release its lock between them.
  void BeginScan(const Eigen::Vector3d& sensor_in_wg);
  void AddPoints(const Eigen::Vector3f* points_in_wg, size_t count, VoxelInsertStats* stats);
  void EndScan(VoxelInsertStats* stats);

  /// Nearest map point within options().max_neighbor_distance_m among the
  /// options().neighborhood voxels around the voxel of `p_in_wg` (centre,
  /// faces, edges, corners, in that order; the first of equally near points
  /// wins). Exact within that neighbourhood: a neighbour voxel is skipped
  /// only when its box is provably farther than the best point so far.
  NearestResult Nearest(const Eigen::Vector3d& p_in_wg) const;
  NearestResult Nearest(const Eigen::Vector3d& p_in_wg, int neighborhood,
                        double max_distance_m) const;

  class LookupCache;
  /// Same result as Nearest(p, neighborhood, max_distance_m), remembering
  /// voxel lookups in `cache` for a caller whose queries move slowly through
  /// space (consecutive ray-march samples share most of their 27 voxels).
  NearestResult Nearest(const Eigen::Vector3d& p_in_wg, int neighborhood, double max_distance_m,
                        LookupCache* cache) const;

  /// Voxel containing a world point: floor(p / voxel_size), clamped far
  /// outside the key range so absurd coordinates cannot overflow the cast.
  VoxelIndex VoxelOf(const Eigen::Vector3d& p_in_wg) const {
    return (p_in_wg * inv_voxel_size_).array().floor().max(-1e9).min(1e9).cast<int>();
  }
  /// True when the voxel holds at least one point (one hash probe).
  bool IsOccupied(const VoxelIndex& voxel) const;

  /// A block of voxels [first, first + edge_voxels - 1] (per axis) in which
  /// no point has a map point in its 27-neighbourhood; edge_voxels == 0
  /// means "not known empty".
  struct EmptyBlock {
    VoxelIndex first = VoxelIndex::Zero();
    int edge_voxels = 0;
  };
  /// The coarse block containing `voxel` if it is empty, else its fine block
  /// if that is empty, else edge_voxels == 0 (always so when skipping is
  /// disabled). One probe into a small table.
  EmptyBlock EmptyBlockAt(const VoxelIndex& voxel) const;

  /// A box [lo, hi] of voxel indices containing every occupied voxel;
  /// false when the grid is empty. Conservative: it grows with insertions
  /// and is recomputed only when evictions sweep the grid.
  bool OccupiedBounds(VoxelIndex* lo, VoxelIndex* hi) const {
    if (table_.size() == 0) return false;
    *lo = bounds_lo_;
    *hi = bounds_hi_;
    return true;
  }

  size_t num_voxels() const { return table_.size(); }
  size_t num_points() const { return num_points_; }
  /// Bytes held by the tables and point storage (capacity, not size).
  size_t MemoryBytes() const;
  /// Every stored point (for tests, export and brute-force references).
  std::vector<Eigen::Vector3f> Points() const;
  /// Points of one voxel (empty if not occupied).
  std::vector<Eigen::Vector3f> PointsInVoxel(const VoxelIndex& voxel) const;
  /// Removes everything.
  void Clear();

 private:
  /// Where a voxel's points are, and how many: kept in the hash slot so a
  /// query touches one table slot and the points, nothing else.
  struct VoxelRef {
    uint32_t slot = 0;
    uint32_t count = 0;
  };
  /// A voxel's stored points as a query sees them.
  struct VoxelSpan {
    const Eigen::Vector3f* points = nullptr;
    uint32_t count = 0;
  };
  using VoxelTable = internal::VoxelHashTable<VoxelRef>;
  using CountTable = internal::VoxelHashTable<uint32_t>;
  static constexpr uint64_t kFreeSlot = VoxelTable::kEmptyKey;
  struct VoxelInfo {
    uint64_t key = kFreeSlot;  ///< kFreeSlot marks a free slot
    uint64_t last_update = 0;  ///< scan counter of the last point received
  };
  using MaskTable = internal::VoxelHashTable<uint64_t>;

  bool KeyOf(const VoxelIndex& voxel, uint64_t* key) const;
  VoxelRef* CreateVoxel(uint64_t key, const VoxelIndex& voxel);
  void EvictSlot(uint32_t slot);
  void UpdateSkipBlocks(const VoxelIndex& voxel, int delta);
  size_t EvictByRadius();
  size_t EvictByCap();
  void RecomputeBounds();
  VoxelIndex VoxelOfSlot(uint32_t slot) const;

  Options options_;
  double inv_voxel_size_ = 10.0;
  int max_points_ = 10;
  VoxelTable table_;                     ///< packed voxel key -> slot, count
  std::vector<VoxelInfo> voxels_;        ///< per slot
  std::vector<Eigen::Vector3f> points_;  ///< max_points_ per slot
  std::vector<uint32_t> free_slots_;
  int fine_block_voxels_ = 0;  ///< skip_block_voxels / 4; 0 = skipping off
  CountTable fine_counts_;     ///< fine block -> occupied voxels whose neighbourhood touches it
  MaskTable coarse_masks_;     ///< coarse block -> bit (x + 4y + 16z) per non-empty fine block
  size_t num_points_ = 0;
  uint64_t scan_counter_ = 0;
  Eigen::Vector3d sensor_in_wg_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_radius_sweep_at_ = Eigen::Vector3d::Zero();
  VoxelIndex bounds_lo_ = VoxelIndex::Constant(std::numeric_limits<int>::max());
  VoxelIndex bounds_hi_ = VoxelIndex::Constant(std::numeric_limits<int>::min());
};

/// Direct-mapped cache of voxel lookups (512 entries, ~12 KB) for one
/// thread. Holds pointers into the grid: valid only while the grid is not
/// modified, so use one per batch of queries under one VoxelMap::Reader, or
/// Clear() it after any insertion.
class VoxelGrid::LookupCache {
 public:
  LookupCache() { Clear(); }
  void Clear() { entries_.fill(Entry{}); }

 private:
  friend class VoxelGrid;
  static constexpr size_t kSize = 512;
  struct Entry {
    uint64_t key = internal::VoxelHashTable<VoxelRef>::kEmptyKey;
    VoxelSpan span;
  };
  std::array<Entry, kSize> entries_;
};

}  // namespace ag
