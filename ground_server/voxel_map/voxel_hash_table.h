#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace ag::internal {

/// Open-addressing hash map from a packed 63-bit voxel key to a small
/// trivially copyable value (<= 8 bytes keeps a slot at 16 bytes).
///
/// Why not std::unordered_map: a plain lookup costs about the same here
/// (tools/bench/map_bench: ~13 ns per probe either way on 2x10^5 voxels, as
/// std::hash<uint64_t> is the identity and keeps neighbouring keys close),
/// but this table (a) stores the voxel's point count next to its key, so a
/// query reads one 16-byte slot per voxel instead of a bucket and a node;
/// (b) lets Nearest() prefetch the slots of all 27 neighbour voxels before
/// probing them, overlapping their cache misses (with the count in the slot
/// and distance pruning this took a near-surface 27-voxel query on a 50 MB
/// map from ~4 us to ~0.9 us); (c) allocates nothing per voxel and
/// erases by backward shift (no tombstones), so lookups stay short under the
/// constant insert/evict churn of a sliding map. Linear probing, load <= 1/2.
template <class Value>
class VoxelHashTable {
 public:
  /// Never a valid key: packed keys use 63 bits (see PackVoxelKey).
  static constexpr uint64_t kEmptyKey = ~uint64_t{0};

  explicit VoxelHashTable(size_t initial_capacity = 64) { Reset(initial_capacity); }

  /// Value of `key`, or nullptr.
  const Value* Find(uint64_t key) const { return Find(key, Hash(key)); }
  /// Same, with `hash` = Hash(key) computed by the caller (see Prefetch).
  const Value* Find(uint64_t key, uint64_t hash) const {
    for (size_t i = hash & mask_;; i = (i + 1) & mask_) {
      const Slot& slot = slots_[i];
      if (slot.key == key) return &slot.value;
      if (slot.key == kEmptyKey) return nullptr;
    }
  }
  /// Starts loading the slot where a lookup of a key with this hash
  /// begins, so several lookups' cache misses overlap.
  void Prefetch(uint64_t hash) const { __builtin_prefetch(&slots_[hash & mask_]); }

  Value* Find(uint64_t key) {
    return const_cast<Value*>(static_cast<const VoxelHashTable*>(this)->Find(key));
  }

  /// Inserts (key, value) if key is absent. Returns the stored value's
  /// address (valid until the next insertion) and whether it was inserted.
  std::pair<Value*, bool> Emplace(uint64_t key, const Value& value) {
    if (2 * (size_ + 1) > slots_.size()) Grow();
    size_t i = Hash(key) & mask_;
    for (;; i = (i + 1) & mask_) {
      Slot& slot = slots_[i];
      if (slot.key == key) return {&slot.value, false};
      if (slot.key == kEmptyKey) break;
    }
    slots_[i] = Slot{key, value};
    ++size_;
    return {&slots_[i].value, true};
  }

  /// Removes `key`; returns false if it was absent. Backward-shift deletion:
  /// later entries of the probe run move up so no tombstone is left.
  bool Erase(uint64_t key) {
    size_t i = Hash(key) & mask_;
    for (;; i = (i + 1) & mask_) {
      if (slots_[i].key == key) break;
      if (slots_[i].key == kEmptyKey) return false;
    }
    for (size_t j = (i + 1) & mask_;; j = (j + 1) & mask_) {
      if (slots_[j].key == kEmptyKey) break;
      const size_t home = Hash(slots_[j].key) & mask_;
      // Entry j may fill the hole at i only if its home is not in (i, j].
      const bool home_in_gap = i <= j ? (i < home && home <= j) : (i < home || home <= j);
      if (home_in_gap) continue;
      slots_[i] = slots_[j];
      i = j;
    }
    slots_[i].key = kEmptyKey;
    --size_;
    return true;
  }

  size_t size() const { return size_; }
  size_t capacity() const { return slots_.size(); }
  size_t MemoryBytes() const { return slots_.capacity() * sizeof(Slot); }

  /// Removes everything and shrinks to `initial_capacity` (rounded up to 2^k).
  void Reset(size_t initial_capacity = 64) {
    size_t capacity = 16;
    while (capacity < initial_capacity) capacity *= 2;
    slots_.assign(capacity, Slot{});
    mask_ = capacity - 1;
    size_ = 0;
  }

  /// Calls fn(key, value) for every entry, in table order.
  template <class Fn>
  void ForEach(Fn&& fn) const {
    for (const Slot& slot : slots_) {
      if (slot.key != kEmptyKey) fn(slot.key, slot.value);
    }
  }

  /// splitmix64 finaliser: packed keys of neighbouring voxels differ in a few
  /// low bits of each field, which a linear-probing table must spread out.
  static uint64_t Hash(uint64_t key) {
    key ^= key >> 30;
    key *= 0xbf58476d1ce4e5b9ULL;
    key ^= key >> 27;
    key *= 0x94d049bb133111ebULL;
    key ^= key >> 31;
    return key;
  }

 private:
  struct Slot {
    uint64_t key = kEmptyKey;
    Value value{};
  };

  void Grow() {
    std::vector<Slot> old;
    old.swap(slots_);
    slots_.assign(old.size() * 2, Slot{});
    mask_ = slots_.size() - 1;
    for (const Slot& slot : old) {
      if (slot.key == kEmptyKey) continue;
      size_t i = Hash(slot.key) & mask_;
      while (slots_[i].key != kEmptyKey) i = (i + 1) & mask_;
      slots_[i] = slot;
    }
  }

  std::vector<Slot> slots_;
  size_t mask_ = 0;
  size_t size_ = 0;
};

/// Packs integer voxel coordinates in [-2^20, 2^20) into 63 bits
/// (21 per axis, offset binary). Callers check the range first.
inline uint64_t PackVoxelKey(int x, int y, int z) {
  constexpr int64_t kOffset = int64_t{1} << 20;
  return (static_cast<uint64_t>(x + kOffset) << 42) | (static_cast<uint64_t>(y + kOffset) << 21) |
         static_cast<uint64_t>(z + kOffset);
}

}  // namespace ag::internal
