#pragma once

// Paper, "Pixel-Point Correspondence": "in a separate thread, point clouds are
// accumulated in a hash table". VoxelMapBuilder is that thread: a bounded
// queue of posed scans in front of VoxelMap::Insert.

#include <Eigen/Core>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

#include "common/core/error.h"
#include "common/geometry/pose.h"
#include "ground_server/voxel_map/voxel_map.h"

namespace ag {

/// One LiDAR scan with its pose in the ground world.
struct PosedScan {
  int64_t t_ns = 0;                       ///< scan time (LiDAR clock, ns)
  std::vector<Eigen::Vector3f> points_l;  ///< points in the LiDAR frame (m)
  Pose T_wg_lidar = Pose::Identity();     ///< LiDAR pose at t_ns (from the odometry buffer)
};

/// Counters of a VoxelMapBuilder.
struct VoxelMapBuilderStats {
  uint64_t scans_pushed = 0;
  uint64_t scans_inserted = 0;
  uint64_t scans_dropped = 0;    ///< pushed out of the full queue (oldest first)
  uint64_t scans_discarded = 0;  ///< still queued when Stop() was called
  uint64_t scans_rejected = 0;   ///< non-finite pose
  /// Pushed scans that are no longer waiting: inserted, dropped, rejected
  /// or discarded.
  uint64_t settled() const {
    return scans_inserted + scans_dropped + scans_rejected + scans_discarded;
  }
  VoxelInsertStats insert;  ///< summed over inserted scans
};

/// Owns an insertion thread that takes scans from a bounded queue,
/// transforms them into the world and inserts them into a VoxelMap.
///
/// When the queue is full, Push drops the oldest queued scan: the map should
/// follow the newest data, and a late old scan is worth less than a fresh
/// one. Stop() lets the scan being inserted finish, discards the rest of the
/// queue (counted) and joins; the destructor calls it.
class VoxelMapBuilder {
 public:
  struct Options {
    int queue_capacity = 4;  ///< scans waiting for insertion; oldest dropped beyond

    template <class V>
    void VisitFields(V& v) {
      v("queue_capacity", queue_capacity);
    }
    void Check() const { CheckOption(queue_capacity >= 1, "queue_capacity", "must be >= 1"); }
  };

  /// `map` must outlive the builder. Does not start the thread.
  explicit VoxelMapBuilder(VoxelMap* map);
  VoxelMapBuilder(VoxelMap* map, const Options& options);
  ~VoxelMapBuilder();
  VoxelMapBuilder(const VoxelMapBuilder&) = delete;
  VoxelMapBuilder& operator=(const VoxelMapBuilder&) = delete;

  /// Starts the insertion thread (no-op if running; not restartable after Stop).
  void Start();

  /// Queues a scan. Returns false (scan not queued) after Stop().
  bool Push(PosedScan scan);

  /// Transforms and inserts one scan on the calling thread; what the thread
  /// does per scan. Rejects (does not insert) a scan with a non-finite pose.
  VoxelInsertStats Process(const PosedScan& scan);

  /// Blocks until the queue is empty and no scan is being inserted, or the
  /// timeout passes. Returns true when idle.
  bool WaitUntilIdle(std::chrono::nanoseconds timeout);

  /// Blocks until the first `pushed` scans ever pushed are settled (inserted,
  /// dropped, rejected or discarded), or the timeout passes; returns true
  /// when they are (or the builder was stopped). With `pushed` =
  /// stats().scans_pushed taken when an image was queued, the map then holds
  /// every scan that came before the image and was not dropped.
  bool WaitUntilSettled(uint64_t pushed, std::chrono::nanoseconds timeout);

  /// Finishes the current scan, discards queued ones, joins. Idempotent.
  void Stop();

  VoxelMapBuilderStats stats() const;
  size_t queue_size() const;

 private:
  void Run();

  VoxelMap* map_;
  Options options_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;  ///< a scan arrived or stop requested
  std::condition_variable idle_;  ///< a scan was settled (the queue may be empty)
  std::deque<PosedScan> queue_;
  bool busy_ = false;
  bool stopping_ = false;
  VoxelMapBuilderStats stats_;
  std::thread thread_;
};

}  // namespace ag
