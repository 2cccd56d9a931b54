#pragma once

#include <Eigen/Core>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <shared_mutex>
#include <vector>

#include "common/core/error.h"
#include "ground_server/voxel_map/voxel_grid.h"

namespace ag {

/// A VoxelGrid shared between inserting threads (whole scans serialised) and
/// any number of querying threads.
///
/// Locking: one std::shared_mutex. Queries take it shared; Insert takes it
/// exclusively for insert_chunk_points points at a time and releases it in
/// between, so a query waits at most one chunk (8192 points: ~2 ms at
/// map_bench's 3.7 Mpoints/s into new voxels, less into full ones) instead
/// of a whole scan. Readers that issue many queries in a row (the depth
/// association marches ~10^4 samples per keyframe) take one Reader for the
/// batch instead of paying the lock per query. Lock striping was not chosen:
/// the open-addressing table rehashes as a whole, and striping its slots
/// would need a lock per probe; tools/bench/map_bench measures the shared
/// lock (query cost with and without a concurrent inserter).
///
/// Neither side starves the other: before touching the shared_mutex every
/// Reader and every chunk of an Insert passes one gate in arrival order (a
/// ticket lock). Readers arriving after a waiting writer queue behind it
/// (glibc's rwlock otherwise prefers readers), and a writer going on to its
/// next chunk queues behind the readers that arrived during the last one (a
/// plain mutex as the gate let it lock again at once, so a reader could wait
/// for the whole backlog of scans).
class VoxelMap {
 public:
  struct Options {
    VoxelGrid::Options grid;
    int insert_chunk_points = 8192;  ///< points inserted per exclusive-lock hold

    template <class V>
    void VisitFields(V& v) {
      v("grid", grid);
      v("insert_chunk_points", insert_chunk_points);
    }
    void Check() const {
      grid.Check();
      CheckOption(insert_chunk_points >= 1, "insert_chunk_points", "must be >= 1");
    }
  };

  /// Shared (read) access to the grid for a batch of queries; holds the
  /// shared lock until destroyed. A thread holding a Reader must not call
  /// any other VoxelMap method (a second shared acquisition can deadlock
  /// behind a waiting writer); query through reader.grid() instead.
  class Reader {
   public:
    const VoxelGrid& grid() const { return *grid_; }
    const VoxelGrid* operator->() const { return grid_; }

   private:
    friend class VoxelMap;
    Reader(const VoxelGrid* grid, std::shared_mutex* mutex) : lock_(*mutex), grid_(grid) {}
    std::shared_lock<std::shared_mutex> lock_;
    const VoxelGrid* grid_;
  };

  VoxelMap();
  /// Throws ag::OptionError if `options` are invalid.
  explicit VoxelMap(const Options& options);

  const Options& options() const { return options_; }

  /// Inserts a scan already in the world frame (see VoxelGrid::Insert).
  VoxelInsertStats Insert(const std::vector<Eigen::Vector3f>& points_in_wg,
                          const Eigen::Vector3d& sensor_in_wg);

  /// Shared access for a batch of queries.
  Reader Read() const;

  /// Single queries, each taking the shared lock.
  NearestResult Nearest(const Eigen::Vector3d& p_in_wg) const;
  bool IsOccupied(const VoxelIndex& voxel) const;
  size_t num_voxels() const;
  size_t num_points() const;
  size_t MemoryBytes() const;
  std::vector<Eigen::Vector3f> Points() const;
  void Clear();

 private:
  /// Passage in order of arrival; a thread keeps its Pass until it holds
  /// mutex_ (readers) or until its chunk is done (writers).
  class FifoGate {
   public:
    class Pass {
     public:
      explicit Pass(FifoGate* gate);
      ~Pass();
      Pass(const Pass&) = delete;
      Pass& operator=(const Pass&) = delete;

     private:
      FifoGate* gate_;
    };

   private:
    std::mutex mutex_;
    std::condition_variable turn_;
    uint64_t next_ticket_ = 0;
    uint64_t serving_ = 0;
  };

  Options options_;
  std::mutex insert_mutex_;  ///< held for a whole Insert (lock order: this, gate_, mutex_)
  mutable FifoGate gate_;
  mutable std::shared_mutex mutex_;
  VoxelGrid grid_;
};

}  // namespace ag
