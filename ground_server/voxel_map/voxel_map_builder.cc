#include "ground_server/voxel_map/voxel_map_builder.h"

#include <utility>

namespace ag {

VoxelMapBuilder::VoxelMapBuilder(VoxelMap* map) : VoxelMapBuilder(map, Options()) {}

VoxelMapBuilder::VoxelMapBuilder(VoxelMap* map, const Options& options)
    : map_(map), options_(options) {
  options_.Check();
}

VoxelMapBuilder::~VoxelMapBuilder() { Stop(); }

void VoxelMapBuilder::Start() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (thread_.joinable() || stopping_) return;
  thread_ = std::thread([this] { Run(); });
}

bool VoxelMapBuilder::Push(PosedScan scan) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_) return false;
    ++stats_.scans_pushed;
    while (queue_.size() >= static_cast<size_t>(options_.queue_capacity)) {
      queue_.pop_front();
      ++stats_.scans_dropped;
    }
    queue_.push_back(std::move(scan));
  }
  wake_.notify_one();
  return true;
}

VoxelInsertStats VoxelMapBuilder::Process(const PosedScan& scan) {
  if (!scan.T_wg_lidar.matrix().allFinite()) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++stats_.scans_rejected;
    return {};
  }
  const Eigen::Matrix3f R = scan.T_wg_lidar.linear().cast<float>();
  const Eigen::Vector3f t = scan.T_wg_lidar.translation().cast<float>();
  std::vector<Eigen::Vector3f> points_in_wg;
  points_in_wg.reserve(scan.points_l.size());
  for (const Eigen::Vector3f& p_l : scan.points_l) points_in_wg.push_back(R * p_l + t);
  const VoxelInsertStats inserted = map_->Insert(points_in_wg, scan.T_wg_lidar.translation());
  std::lock_guard<std::mutex> lock(mutex_);
  ++stats_.scans_inserted;
  stats_.insert.Accumulate(inserted);
  return inserted;
}

void VoxelMapBuilder::Run() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (stopping_) break;
    PosedScan scan = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    lock.unlock();
    Process(scan);
    lock.lock();
    busy_ = false;
    idle_.notify_all();
  }
  stats_.scans_discarded += queue_.size();
  queue_.clear();
  busy_ = false;
  idle_.notify_all();
}

bool VoxelMapBuilder::WaitUntilIdle(std::chrono::nanoseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  return idle_.wait_for(lock, timeout, [this] { return queue_.empty() && !busy_; });
}

bool VoxelMapBuilder::WaitUntilSettled(uint64_t pushed, std::chrono::nanoseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  return idle_.wait_for(lock, timeout, [&] { return stats_.settled() >= pushed || stopping_; });
}

void VoxelMapBuilder::Stop() {
  std::thread thread;  // taken out under the lock so concurrent Stop()s join once
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    thread.swap(thread_);
    if (!thread.joinable()) {
      stats_.scans_discarded += queue_.size();
      queue_.clear();
    }
  }
  wake_.notify_all();
  if (thread.joinable()) thread.join();
}

VoxelMapBuilderStats VoxelMapBuilder::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

size_t VoxelMapBuilder::queue_size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.size();
}

}  // namespace ag
