#pragma once

// A thin owner of one hnswlib graph over L2-normalised float vectors with
// inner-product similarity (internal to ag::place_db).
//
// hnsw_index.cc is the only translation unit that includes hnswlib: the
// 0.6.2 header defines non-inline functions (cpuid, AVXCapable) unless
// NO_MANUAL_VECTORIZATION is set, so another .cc including it differently
// would not link. Keep it that way: nothing else includes <hnswlib/...>.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace hnswlib {
template <typename dist_t>
class HierarchicalNSW;
template <typename dist_t>
class SpaceInterface;
}  // namespace hnswlib

namespace ag::internal {

/// Labels are slots: slot i is hnswlib's internal element i, so a slot can
/// be marked deleted and later refilled with another vector (hnswlib then
/// re-links it in place), which keeps the graph size bounded under eviction.
/// The graph navigates on int8 codes of the vectors; the float vectors are
/// kept beside it and re-rank every search, so similarities are exact.
class HnswIndex {
 public:
  /// An empty graph with room for `capacity` vectors of `dim` floats.
  HnswIndex(int dim, int m, int ef_construction, size_t capacity, unsigned random_seed);
  ~HnswIndex();
  HnswIndex(const HnswIndex&) = delete;
  HnswIndex& operator=(const HnswIndex&) = delete;

  /// Reads a graph written by Save(). Throws std::runtime_error when the
  /// file does not hold a graph of `dim`-D codes with slot labels. The float
  /// vectors are not in the file: RestoreVector each live slot afterwards.
  static std::unique_ptr<HnswIndex> Load(const std::string& path, int dim);

  /// Writes the graph with its codes (hnswlib's saveIndex) and checks that
  /// the file has the size the graph needs; throws std::runtime_error
  /// otherwise (disk full).
  void Save(const std::string& path) const;

  /// After Load: gives a filled slot its float vector back. False when the
  /// slot does not exist or its code in the graph is not this vector's.
  bool RestoreVector(size_t slot, const float* vector);

  /// Puts `vector` (dim floats, unit norm) in `slot`. slot == Slots() appends
  /// (doubling the capacity when full, no rebuild); slot < Slots() must be a
  /// deleted slot, which is refilled and re-linked.
  void Put(size_t slot, const float* vector);

  /// Hides `slot` from searches; it stays in the graph as a waypoint.
  void MarkDeleted(size_t slot);
  bool IsDeleted(size_t slot) const;

  /// The k most similar live slots, best first (ties: lower slot), as
  /// (exact inner product, slot): the max(ef, k) candidates of the graph
  /// search re-ranked with the float vectors. Thread-safe against other
  /// Search calls (not against Put/MarkDeleted/SetEf).
  std::vector<std::pair<float, size_t>> Search(const float* query, size_t k) const;

  /// Candidate list size of a search (hnswlib's ef); not thread-safe.
  void SetEf(size_t ef);

  size_t Slots() const;         ///< slots ever filled (live + deleted)
  size_t DeletedSlots() const;  ///< slots marked deleted
  size_t Capacity() const;      ///< slots allocated
  int64_t MemoryBytes() const;  ///< estimate of heap memory held by the graph

 private:
  HnswIndex() = default;

  size_t dim_ = 0;
  std::unique_ptr<hnswlib::SpaceInterface<float>> space_;
  std::unique_ptr<hnswlib::HierarchicalNSW<float>> graph_;
  std::vector<float> exact_;  ///< Capacity() x dim unit vectors, by slot
};

}  // namespace ag::internal
