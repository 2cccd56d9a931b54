#include "ground_server/voxel_map/voxel_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace ag {
namespace {

// Keys hold 21 bits per axis; one voxel of margin keeps every neighbour and
// dilated block of a stored voxel representable too.
constexpr int kMinCoord = -(1 << 20) + 1;
constexpr int kMaxCoord = (1 << 20) - 2;

// Neighbourhood offsets in search order: centre, 6 faces, 12 edges, 8
// corners, so the first 7 / 19 / 27 are the three neighbourhood sizes.
constexpr int kOffsets[27][3] = {
    {0, 0, 0},                                                                    // centre
    {-1, 0, 0},   {1, 0, 0},   {0, -1, 0},  {0, 1, 0},  {0, 0, -1},  {0, 0, 1},   // faces
    {-1, -1, 0},  {-1, 1, 0},  {1, -1, 0},  {1, 1, 0},  {-1, 0, -1}, {-1, 0, 1},  // edges
    {1, 0, -1},   {1, 0, 1},   {0, -1, -1}, {0, -1, 1}, {0, 1, -1},  {0, 1, 1},   //
    {-1, -1, -1}, {-1, -1, 1}, {-1, 1, -1}, {-1, 1, 1},                           // corners
    {1, -1, -1},  {1, -1, 1},  {1, 1, -1},  {1, 1, 1}};

// Slack (m) subtracted from voxel-face distances in the nearest-neighbour
// pruning bound; far above the rounding of floor(p / voxel_size).
constexpr double kBoundSlack = 1e-9;

int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

bool InKeyRange(const VoxelIndex& v) {
  return v.minCoeff() >= kMinCoord && v.maxCoeff() <= kMaxCoord;
}

uint64_t Pack(const VoxelIndex& v) { return internal::PackVoxelKey(v.x(), v.y(), v.z()); }

VoxelIndex Unpack(uint64_t key) {
  constexpr int64_t kOffset = int64_t{1} << 20;
  constexpr uint64_t kMask = (uint64_t{1} << 21) - 1;
  return VoxelIndex(static_cast<int>(static_cast<int64_t>((key >> 42) & kMask) - kOffset),
                    static_cast<int>(static_cast<int64_t>((key >> 21) & kMask) - kOffset),
                    static_cast<int>(static_cast<int64_t>(key & kMask) - kOffset));
}

}  // namespace

void VoxelInsertStats::Accumulate(const VoxelInsertStats& other) {
  points_added += other.points_added;
  points_voxel_full += other.points_voxel_full;
  points_replaced += other.points_replaced;
  points_rejected += other.points_rejected;
  points_beyond_radius += other.points_beyond_radius;
  voxels_created += other.voxels_created;
  voxels_evicted_radius += other.voxels_evicted_radius;
  voxels_evicted_cap += other.voxels_evicted_cap;
}

void VoxelGrid::Options::Check() const {
  CheckOption(std::isfinite(voxel_size_m) && voxel_size_m > 0, "voxel_size_m", "must be > 0");
  CheckOption(max_points_per_voxel >= 1 && max_points_per_voxel <= 1000, "max_points_per_voxel",
              "must be in [1, 1000]");
  CheckOption(max_voxels >= 1, "max_voxels", "must be >= 1");
  CheckOption(std::isfinite(eviction_radius_m) && eviction_radius_m >= 0, "eviction_radius_m",
              "must be >= 0 (0 disables)");
  CheckOption(neighborhood == 7 || neighborhood == 19 || neighborhood == 27, "neighborhood",
              "must be 7, 19 or 27");
  CheckOption(std::isfinite(max_neighbor_distance_m) && max_neighbor_distance_m > 0,
              "max_neighbor_distance_m", "must be > 0");
  CheckOption(skip_block_voxels >= 0 && skip_block_voxels <= 1024 && skip_block_voxels % 4 == 0,
              "skip_block_voxels", "must be a multiple of 4 in [0, 1024] (0 disables)");
}

VoxelGrid::VoxelGrid() : VoxelGrid(Options()) {}

VoxelGrid::VoxelGrid(const Options& options) : options_(options) {
  options_.Check();
  inv_voxel_size_ = 1.0 / options_.voxel_size_m;
  max_points_ = options_.max_points_per_voxel;
  fine_block_voxels_ = options_.skip_block_voxels / 4;
}

bool VoxelGrid::KeyOf(const VoxelIndex& voxel, uint64_t* key) const {
  if (!InKeyRange(voxel)) return false;
  *key = Pack(voxel);
  return true;
}

VoxelIndex VoxelGrid::VoxelOfSlot(uint32_t slot) const { return Unpack(voxels_[slot].key); }

VoxelGrid::EmptyBlock VoxelGrid::EmptyBlockAt(const VoxelIndex& voxel) const {
  const int f = fine_block_voxels_;
  if (f == 0) return EmptyBlock{voxel, 0};
  // Outside the packable range nothing is stored within one voxel.
  constexpr int kPackMin = -(1 << 20);
  constexpr int kPackMax = (1 << 20) - 1;
  if (voxel.minCoeff() < kPackMin || voxel.maxCoeff() > kPackMax) return EmptyBlock{voxel, 1};
  const VoxelIndex fine(FloorDiv(voxel.x(), f), FloorDiv(voxel.y(), f), FloorDiv(voxel.z(), f));
  const VoxelIndex coarse(FloorDiv(fine.x(), 4), FloorDiv(fine.y(), 4), FloorDiv(fine.z(), 4));
  const uint64_t* mask = coarse_masks_.Find(Pack(coarse));
  if (mask == nullptr) return EmptyBlock{coarse * (4 * f), 4 * f};
  const VoxelIndex local = fine - 4 * coarse;
  const int bit = local.x() + 4 * local.y() + 16 * local.z();
  if (((*mask >> bit) & 1u) == 0) return EmptyBlock{fine * f, f};
  return EmptyBlock{voxel, 0};
}

bool VoxelGrid::IsOccupied(const VoxelIndex& voxel) const {
  uint64_t key = 0;
  return KeyOf(voxel, &key) && table_.Find(key) != nullptr;
}

void VoxelGrid::UpdateSkipBlocks(const VoxelIndex& voxel, int delta) {
  const int f = fine_block_voxels_;
  if (f == 0) return;
  const VoxelIndex lo(FloorDiv(voxel.x() - 1, f), FloorDiv(voxel.y() - 1, f),
                      FloorDiv(voxel.z() - 1, f));
  const VoxelIndex hi(FloorDiv(voxel.x() + 1, f), FloorDiv(voxel.y() + 1, f),
                      FloorDiv(voxel.z() + 1, f));
  for (int x = lo.x(); x <= hi.x(); ++x) {
    for (int y = lo.y(); y <= hi.y(); ++y) {
      for (int z = lo.z(); z <= hi.z(); ++z) {
        const uint64_t key = internal::PackVoxelKey(x, y, z);
        const VoxelIndex coarse(FloorDiv(x, 4), FloorDiv(y, 4), FloorDiv(z, 4));
        const int bit = (x - 4 * coarse.x()) + 4 * (y - 4 * coarse.y()) + 16 * (z - 4 * coarse.z());
        if (delta > 0) {
          uint32_t* count = fine_counts_.Emplace(key, 0).first;
          if (++*count == 1) *coarse_masks_.Emplace(Pack(coarse), 0).first |= uint64_t{1} << bit;
        } else {
          uint32_t* count = fine_counts_.Find(key);
          if (count == nullptr || --*count > 0) continue;
          fine_counts_.Erase(key);
          const uint64_t coarse_key = Pack(coarse);
          uint64_t* mask = coarse_masks_.Find(coarse_key);
          if (mask == nullptr) continue;
          *mask &= ~(uint64_t{1} << bit);
          if (*mask == 0) coarse_masks_.Erase(coarse_key);
        }
      }
    }
  }
}

VoxelGrid::VoxelRef* VoxelGrid::CreateVoxel(uint64_t key, const VoxelIndex& voxel) {
  uint32_t slot = 0;
  if (!free_slots_.empty()) {
    slot = free_slots_.back();
    free_slots_.pop_back();
  } else {
    slot = static_cast<uint32_t>(voxels_.size());
    voxels_.emplace_back();
    points_.resize(points_.size() + static_cast<size_t>(max_points_));
  }
  voxels_[slot] = VoxelInfo{key, scan_counter_};
  UpdateSkipBlocks(voxel, +1);
  bounds_lo_ = bounds_lo_.cwiseMin(voxel);
  bounds_hi_ = bounds_hi_.cwiseMax(voxel);
  return table_.Emplace(key, VoxelRef{slot, 0}).first;
}

void VoxelGrid::EvictSlot(uint32_t slot) {
  VoxelInfo& info = voxels_[slot];
  UpdateSkipBlocks(Unpack(info.key), -1);
  num_points_ -= table_.Find(info.key)->count;
  table_.Erase(info.key);
  info = VoxelInfo{};
  free_slots_.push_back(slot);
}

VoxelInsertStats VoxelGrid::Insert(const std::vector<Eigen::Vector3f>& points_in_wg,
                                   const Eigen::Vector3d& sensor_in_wg) {
  VoxelInsertStats stats;
  BeginScan(sensor_in_wg);
  AddPoints(points_in_wg.data(), points_in_wg.size(), &stats);
  EndScan(&stats);
  return stats;
}

void VoxelGrid::BeginScan(const Eigen::Vector3d& sensor_in_wg) {
  if (scan_counter_ == 0) last_radius_sweep_at_ = sensor_in_wg;
  ++scan_counter_;
  sensor_in_wg_ = sensor_in_wg;
}

void VoxelGrid::AddPoints(const Eigen::Vector3f* points_in_wg, size_t count,
                          VoxelInsertStats* stats) {
  const double radius2 = options_.eviction_radius_m * options_.eviction_radius_m;
  for (size_t i = 0; i < count; ++i) {
    const Eigen::Vector3f& p = points_in_wg[i];
    if (!p.allFinite()) {
      ++stats->points_rejected;
      continue;
    }
    const Eigen::Vector3d p_d = p.cast<double>();
    if (radius2 > 0 && (p_d - sensor_in_wg_).squaredNorm() > radius2) {
      ++stats->points_beyond_radius;
      continue;
    }
    const VoxelIndex voxel = VoxelOf(p_d);
    uint64_t key = 0;
    if (!KeyOf(voxel, &key)) {
      ++stats->points_rejected;
      continue;
    }
    VoxelRef* ref = table_.Find(key);
    if (ref == nullptr) {
      ref = CreateVoxel(key, voxel);
      ++stats->voxels_created;
    }
    voxels_[ref->slot].last_update = scan_counter_;
    Eigen::Vector3f* stored = &points_[static_cast<size_t>(ref->slot) * max_points_];
    if (ref->count < static_cast<uint32_t>(max_points_)) {
      stored[ref->count] = p;
      ++ref->count;
      ++num_points_;
      ++stats->points_added;
    } else if (options_.keep_latest) {
      // Kept in arrival order: drop the first, append the new one.
      std::move(stored + 1, stored + max_points_, stored);
      stored[max_points_ - 1] = p;
      ++stats->points_replaced;
    } else {
      ++stats->points_voxel_full;
    }
  }
}

void VoxelGrid::EndScan(VoxelInsertStats* stats) {
  size_t evicted = 0;
  const double radius = options_.eviction_radius_m;
  if (radius > 0 && (sensor_in_wg_ - last_radius_sweep_at_).norm() > 0.05 * radius) {
    const size_t n = EvictByRadius();
    stats->voxels_evicted_radius += n;
    evicted += n;
    last_radius_sweep_at_ = sensor_in_wg_;
  }
  if (table_.size() > static_cast<size_t>(options_.max_voxels)) {
    const size_t n = EvictByCap();
    stats->voxels_evicted_cap += n;
    evicted += n;
  }
  if (evicted > 0) RecomputeBounds();
}

void VoxelGrid::RecomputeBounds() {
  bounds_lo_ = VoxelIndex::Constant(std::numeric_limits<int>::max());
  bounds_hi_ = VoxelIndex::Constant(std::numeric_limits<int>::min());
  for (const VoxelInfo& info : voxels_) {
    if (info.key == kFreeSlot) continue;
    const VoxelIndex v = Unpack(info.key);
    bounds_lo_ = bounds_lo_.cwiseMin(v);
    bounds_hi_ = bounds_hi_.cwiseMax(v);
  }
}

size_t VoxelGrid::EvictByRadius() {
  const double radius2 = options_.eviction_radius_m * options_.eviction_radius_m;
  size_t evicted = 0;
  for (uint32_t slot = 0; slot < voxels_.size(); ++slot) {
    if (voxels_[slot].key == kFreeSlot) continue;
    const Eigen::Vector3d centre =
        (VoxelOfSlot(slot).cast<double>().array() + 0.5) * options_.voxel_size_m;
    if ((centre - sensor_in_wg_).squaredNorm() > radius2) {
      EvictSlot(slot);
      ++evicted;
    }
  }
  return evicted;
}

size_t VoxelGrid::EvictByCap() {
  const size_t cap = static_cast<size_t>(options_.max_voxels);
  const size_t target = cap - cap / 10;
  const size_t excess = table_.size() - target;
  std::vector<std::pair<uint64_t, uint32_t>> age;  // (last_update, slot)
  age.reserve(table_.size());
  for (uint32_t slot = 0; slot < voxels_.size(); ++slot) {
    if (voxels_[slot].key != kFreeSlot) {
      age.emplace_back(voxels_[slot].last_update, slot);
    }
  }
  std::nth_element(age.begin(), age.begin() + static_cast<std::ptrdiff_t>(excess), age.end());
  for (size_t i = 0; i < excess; ++i) EvictSlot(age[i].second);
  return excess;
}

NearestResult VoxelGrid::Nearest(const Eigen::Vector3d& p_in_wg, int neighborhood,
                                 double max_distance_m) const {
  return Nearest(p_in_wg, neighborhood, max_distance_m, nullptr);
}

NearestResult VoxelGrid::Nearest(const Eigen::Vector3d& p_in_wg, int neighborhood,
                                 double max_distance_m, LookupCache* cache) const {
  NearestResult result;
  if (!p_in_wg.allFinite()) return result;
  const VoxelIndex voxel = VoxelOf(p_in_wg);
  if (!InKeyRange(voxel)) return result;
  // Squared distance from the query to the voxel faces below / above it on
  // each axis, less a nanometre so rounding in the voxel assignment of
  // stored points cannot make the bound exceed a true distance.
  const double size = options_.voxel_size_m;
  const Eigen::Vector3d below = p_in_wg - voxel.cast<double>() * size;
  Eigen::Array3d gap2[2];
  for (int a = 0; a < 3; ++a) {
    const double lo = std::max(0.0, below[a] - kBoundSlack);
    const double hi = std::max(0.0, size - below[a] - kBoundSlack);
    gap2[0][a] = lo * lo;
    gap2[1][a] = hi * hi;
  }
  double best2 = max_distance_m * max_distance_m;
  // The lookups are memory-bound (a cache miss per table slot and per
  // voxel's points), so first start every load that can matter, then
  // search in the fixed order with the pruning bound.
  struct Candidate {
    double box2;
    uint64_t key;
    uint64_t hash;
    VoxelSpan span;
  };
  std::array<Candidate, 27> candidates;
  int n = 0;
  for (int i = 0; i < neighborhood; ++i) {
    const int* off = kOffsets[i];
    double box2 = 0.0;
    for (int a = 0; a < 3; ++a) {
      if (off[a] != 0) box2 += gap2[off[a] > 0 ? 1 : 0][a];
    }
    if (box2 > best2) continue;  // beyond max_distance_m
    const VoxelIndex v = voxel + VoxelIndex(off[0], off[1], off[2]);
    if (!InKeyRange(v)) continue;
    const uint64_t key = Pack(v);
    const uint64_t hash = VoxelTable::Hash(key);
    if (cache == nullptr || cache->entries_[hash & (LookupCache::kSize - 1)].key != key) {
      table_.Prefetch(hash);
    }
    candidates[n++] = Candidate{box2, key, hash, VoxelSpan{}};
  }
  for (int c = 0; c < n; ++c) {
    Candidate& candidate = candidates[c];
    LookupCache::Entry* entry =
        cache != nullptr ? &cache->entries_[candidate.hash & (LookupCache::kSize - 1)] : nullptr;
    if (entry != nullptr && entry->key == candidate.key) {
      candidate.span = entry->span;
      continue;
    }
    const VoxelRef* ref = table_.Find(candidate.key, candidate.hash);
    if (ref != nullptr) {
      candidate.span.points = &points_[static_cast<size_t>(ref->slot) * max_points_];
      candidate.span.count = ref->count;
      __builtin_prefetch(candidate.span.points);
    }
    if (entry != nullptr) *entry = LookupCache::Entry{candidate.key, candidate.span};
  }
  const Eigen::Vector3f* best = nullptr;
  for (int c = 0; c < n; ++c) {
    const VoxelSpan& span = candidates[c].span;
    // Skip voxels whose every point is farther than the best so far.
    if (span.count == 0 || candidates[c].box2 > best2) continue;
    for (uint32_t k = 0; k < span.count; ++k) {
      const double d2 = (span.points[k].cast<double>() - p_in_wg).squaredNorm();
      // Strict '<' keeps the first of equally near points; '<=' on the very
      // first accepts a point exactly at max_distance_m.
      if (d2 < best2 || (best == nullptr && d2 == best2)) {
        best2 = d2;
        best = &span.points[k];
      }
    }
  }
  if (best != nullptr) {
    result.found = true;
    result.point = *best;
    result.distance_m = std::sqrt(best2);
  }
  return result;
}

NearestResult VoxelGrid::Nearest(const Eigen::Vector3d& p_in_wg) const {
  return Nearest(p_in_wg, options_.neighborhood, options_.max_neighbor_distance_m);
}

size_t VoxelGrid::MemoryBytes() const {
  size_t bytes = table_.MemoryBytes() + voxels_.capacity() * sizeof(VoxelInfo) +
                 points_.capacity() * sizeof(Eigen::Vector3f) +
                 free_slots_.capacity() * sizeof(uint32_t);
  bytes += fine_counts_.MemoryBytes() + coarse_masks_.MemoryBytes();
  return bytes;
}

std::vector<Eigen::Vector3f> VoxelGrid::Points() const {
  std::vector<Eigen::Vector3f> out;
  out.reserve(num_points_);
  table_.ForEach([&](uint64_t, const VoxelRef& ref) {
    const size_t base = static_cast<size_t>(ref.slot) * max_points_;
    for (uint32_t i = 0; i < ref.count; ++i) out.push_back(points_[base + i]);
  });
  return out;
}

std::vector<Eigen::Vector3f> VoxelGrid::PointsInVoxel(const VoxelIndex& voxel) const {
  std::vector<Eigen::Vector3f> out;
  uint64_t key = 0;
  if (!KeyOf(voxel, &key)) return out;
  const VoxelRef* ref = table_.Find(key);
  if (ref == nullptr) return out;
  const size_t base = static_cast<size_t>(ref->slot) * max_points_;
  out.assign(points_.begin() + static_cast<std::ptrdiff_t>(base),
             points_.begin() + static_cast<std::ptrdiff_t>(base + ref->count));
  return out;
}

void VoxelGrid::Clear() {
  table_.Reset();
  voxels_.clear();
  points_.clear();
  free_slots_.clear();
  fine_counts_.Reset();
  coarse_masks_.Reset();
  num_points_ = 0;
  scan_counter_ = 0;
  RecomputeBounds();
}

}  // namespace ag
