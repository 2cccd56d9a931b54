#include "ground_server/voxel_map/voxel_map.h"

#include <algorithm>

namespace ag {

VoxelMap::VoxelMap() : VoxelMap(Options()) {}

VoxelMap::VoxelMap(const Options& options) : options_(options), grid_(options.grid) {
  options_.Check();
}

VoxelMap::FifoGate::Pass::Pass(FifoGate* gate) : gate_(gate) {
  std::unique_lock<std::mutex> lock(gate_->mutex_);
  const uint64_t ticket = gate_->next_ticket_++;
  gate_->turn_.wait(lock, [&] { return gate_->serving_ == ticket; });
}

VoxelMap::FifoGate::Pass::~Pass() {
  {
    std::lock_guard<std::mutex> lock(gate_->mutex_);
    ++gate_->serving_;
  }
  gate_->turn_.notify_all();
}

VoxelMap::Reader VoxelMap::Read() const {
  // The shared lock is taken while holding the pass, so a writer that
  // arrived earlier is served first.
  const FifoGate::Pass pass(&gate_);
  return Reader(&grid_, &mutex_);
}

VoxelInsertStats VoxelMap::Insert(const std::vector<Eigen::Vector3f>& points_in_wg,
                                  const Eigen::Vector3d& sensor_in_wg) {
  // Whole scans are serialised: BeginScan/EndScan of two inserters must not
  // interleave.
  std::lock_guard<std::mutex> one_scan_at_a_time(insert_mutex_);
  VoxelInsertStats stats;
  const size_t chunk = static_cast<size_t>(options_.insert_chunk_points);
  {
    const FifoGate::Pass pass(&gate_);
    std::unique_lock<std::shared_mutex> lock(mutex_);
    grid_.BeginScan(sensor_in_wg);
  }
  for (size_t begin = 0; begin < points_in_wg.size(); begin += chunk) {
    const size_t count = std::min(chunk, points_in_wg.size() - begin);
    const FifoGate::Pass pass(&gate_);
    std::unique_lock<std::shared_mutex> lock(mutex_);
    grid_.AddPoints(points_in_wg.data() + begin, count, &stats);
  }
  {
    const FifoGate::Pass pass(&gate_);
    std::unique_lock<std::shared_mutex> lock(mutex_);
    grid_.EndScan(&stats);
  }
  return stats;
}

NearestResult VoxelMap::Nearest(const Eigen::Vector3d& p_in_wg) const {
  return Read()->Nearest(p_in_wg);
}

bool VoxelMap::IsOccupied(const VoxelIndex& voxel) const { return Read()->IsOccupied(voxel); }

size_t VoxelMap::num_voxels() const { return Read()->num_voxels(); }

size_t VoxelMap::num_points() const { return Read()->num_points(); }

size_t VoxelMap::MemoryBytes() const { return Read()->MemoryBytes(); }

std::vector<Eigen::Vector3f> VoxelMap::Points() const { return Read()->Points(); }

void VoxelMap::Clear() {
  std::lock_guard<std::mutex> one_scan_at_a_time(insert_mutex_);
  const FifoGate::Pass pass(&gate_);
  std::unique_lock<std::shared_mutex> lock(mutex_);
  grid_.Clear();
}

}  // namespace ag
