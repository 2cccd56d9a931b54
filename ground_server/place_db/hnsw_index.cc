#include "ground_server/place_db/hnsw_index.h"

// hnswlib's SSE code path is off: the distances below are our own, so all it
// would add is prefetching, which in 0.6.2 reads one link past the end of a
// link list (AddressSanitizer reports it) and measured no faster here. It
// also keeps hnswlib.h from defining its non-inline cpuid/AVXCapable.
#define NO_MANUAL_VECTORIZATION
#include <hnswlib/hnswlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <stdexcept>

namespace ag::internal {

namespace {

using Graph = hnswlib::HierarchicalNSW<float>;

// Vectors live in the graph as int8 codes (SQ8): q_i = round(x_i / scale),
// scale = max |x_i| / 127, followed by the float scale. A 512-D vector then
// takes 516 bytes instead of 2048, and a query, which visits a thousand or
// so nodes scattered in memory, is bound by those bytes: at 10k entries the
// float graph no longer fits in cache and ran 3-4x slower than at 1k. The
// codes only steer the search; Search() re-ranks its candidates with the
// exact float vectors (kept apart, touched ef times per query), so returned
// similarities are exact.
//
// Both dot products use independent partial sums so the compiler keeps
// several vector accumulators in flight (hnswlib's own SSE kernel chains
// every addition through one register). On x86-64 an AVX2 clone is chosen
// at run time; elsewhere (ARM64: NEON) the default build is vectorised.
#if defined(__x86_64__) && defined(__has_attribute)
#if __has_attribute(target_clones)
#define AG_PLACE_DB_CLONES __attribute__((target_clones("avx2", "default")))
#endif
#endif
#ifndef AG_PLACE_DB_CLONES
#define AG_PLACE_DB_CLONES
#endif

AG_PLACE_DB_CLONES float Dot(const float* x, const float* y, size_t dim) {
  constexpr size_t kLanes = 16;
  float partial[kLanes] = {};
  size_t i = 0;
  for (; i + kLanes <= dim; i += kLanes) {
    for (size_t j = 0; j < kLanes; ++j) partial[j] += x[i + j] * y[i + j];
  }
  float sum = 0;
  for (; i < dim; ++i) sum += x[i] * y[i];
  for (size_t j = 0; j < kLanes; ++j) sum += partial[j];
  return sum;
}

AG_PLACE_DB_CLONES int32_t CodeDot(const int8_t* x, const int8_t* y, size_t dim) {
  int32_t sum = 0;  // |sum| <= dim * 127^2: no overflow below dim 133k
  for (size_t i = 0; i < dim; ++i) sum += int32_t{x[i]} * int32_t{y[i]};
  return sum;
}

float CodeScale(const void* code, size_t dim) {
  float scale = 0;
  std::memcpy(&scale, static_cast<const char*>(code) + dim, sizeof(scale));
  return scale;
}

/// hnswlib distance between two codes: 1 - approximate inner product.
float CodeDistance(const void* a, const void* b, const void* dim_ptr) {
  const size_t dim = *static_cast<const size_t*>(dim_ptr);
  const int32_t dot = CodeDot(static_cast<const int8_t*>(a), static_cast<const int8_t*>(b), dim);
  return 1.0F - CodeScale(a, dim) * CodeScale(b, dim) * static_cast<float>(dot);
}

/// hnswlib's view of the codes: dim int8 values and a float scale.
class CodeSpace : public hnswlib::SpaceInterface<float> {
 public:
  explicit CodeSpace(size_t dim) : dim_(dim) {}
  size_t get_data_size() override { return dim_ + sizeof(float); }
  hnswlib::DISTFUNC<float> get_dist_func() override { return &CodeDistance; }
  void* get_dist_func_param() override { return &dim_; }

 private:
  size_t dim_;
};

std::vector<char> Encode(const float* x, size_t dim) {
  float max_abs = 0;
  for (size_t i = 0; i < dim; ++i) max_abs = std::max(max_abs, std::abs(x[i]));
  const float scale = max_abs / 127.0F;
  const float inverse = scale > 0 ? 1.0F / scale : 0.0F;
  std::vector<char> code(dim + sizeof(float));
  for (size_t i = 0; i < dim; ++i) {
    const float q = std::clamp(std::nearbyint(x[i] * inverse), -127.0F, 127.0F);
    code[i] = static_cast<char>(static_cast<int8_t>(q));
  }
  std::memcpy(code.data() + dim, &scale, sizeof(scale));
  return code;
}

// Bytes hnswlib 0.6.2's saveIndex writes for `graph`: a fixed header of 13
// fields, level 0 of every element, then per element a u32 size and its upper
// levels. Save() compares the file against it because saveIndex does not
// report write errors; a mismatch means the disk filled up or the library
// changed its format, and either way the file must not become a snapshot.
uint64_t ExpectedFileSize(const Graph& g) {
  uint64_t size = sizeof(g.offsetLevel0_) + sizeof(g.max_elements_) + sizeof(g.cur_element_count) +
                  sizeof(g.size_data_per_element_) + sizeof(g.label_offset_) +
                  sizeof(g.offsetData_) + sizeof(g.maxlevel_) + sizeof(g.enterpoint_node_) +
                  sizeof(g.maxM_) + sizeof(g.maxM0_) + sizeof(g.M_) + sizeof(g.mult_) +
                  sizeof(g.ef_construction_);
  size += uint64_t{g.cur_element_count} * g.size_data_per_element_;
  for (size_t i = 0; i < g.cur_element_count; ++i) {
    size += sizeof(unsigned int);
    if (g.element_levels_[i] > 0)
      size += uint64_t{g.size_links_per_element_} * g.element_levels_[i];
  }
  return size;
}

}  // namespace

HnswIndex::HnswIndex(int dim, int m, int ef_construction, size_t capacity, unsigned random_seed)
    : dim_(static_cast<size_t>(dim)),
      space_(std::make_unique<CodeSpace>(dim_)),
      graph_(std::make_unique<Graph>(space_.get(), std::max<size_t>(capacity, 1),
                                     static_cast<size_t>(m), static_cast<size_t>(ef_construction),
                                     random_seed)),
      exact_(graph_->max_elements_ * dim_) {}

HnswIndex::~HnswIndex() = default;

std::unique_ptr<HnswIndex> HnswIndex::Load(const std::string& path, int dim) {
  std::unique_ptr<HnswIndex> index(new HnswIndex());
  index->dim_ = static_cast<size_t>(dim);
  index->space_ = std::make_unique<CodeSpace>(index->dim_);
  // hnswlib 0.6.2's loading constructor leaves num_deleted_ and the metric
  // counters uninitialised before adding to them. Start from a properly
  // constructed one-slot graph instead, release its buffers, and let
  // loadIndex allocate them again from the file.
  index->graph_ = std::make_unique<Graph>(index->space_.get(), 1);
  Graph& g = *index->graph_;
  std::free(g.data_level0_memory_);
  std::free(g.linkLists_);
  delete g.visited_list_pool_;
  g.data_level0_memory_ = nullptr;
  g.linkLists_ = nullptr;
  g.visited_list_pool_ = nullptr;
  try {
    g.loadIndex(path, index->space_.get());
  } catch (const std::exception& e) {
    // Leave a state the destructor can free: no elements, no link lists.
    g.cur_element_count = 0;
    throw std::runtime_error(std::string("hnswlib cannot read the graph: ") + e.what());
  }
  if (g.label_offset_ != g.offsetData_ + index->space_->get_data_size()) {
    throw std::runtime_error("graph holds vectors of another dimension than " +
                             std::to_string(dim));
  }
  for (size_t i = 0; i < g.cur_element_count; ++i) {
    if (g.getExternalLabel(static_cast<hnswlib::tableint>(i)) != i) {
      throw std::runtime_error("graph element " + std::to_string(i) + " has label " +
                               std::to_string(g.getExternalLabel(i)) + ", expected its slot");
    }
  }
  index->exact_.assign(g.max_elements_ * index->dim_, 0.0F);
  return index;
}

void HnswIndex::Save(const std::string& path) const {
  graph_->saveIndex(path);
  const uint64_t expected = ExpectedFileSize(*graph_);
  std::error_code ec;
  const uint64_t actual = std::filesystem::file_size(path, ec);
  if (ec || actual != expected) {
    throw std::runtime_error("writing the HNSW graph to " + path + " failed: " +
                             (ec ? ec.message()
                                 : std::to_string(actual) + " bytes written, " +
                                       std::to_string(expected) + " expected (disk full?)"));
  }
}

void HnswIndex::Put(size_t slot, const float* vector) {
  Graph& g = *graph_;
  if (slot > g.cur_element_count) throw std::logic_error("HnswIndex::Put: slot beyond the end");
  const std::vector<char> code = Encode(vector, dim_);
  if (slot < g.cur_element_count) {
    if (!IsDeleted(slot)) throw std::logic_error("HnswIndex::Put: slot is in use");
    // addPoint with an existing label unmarks the slot and re-links it to
    // the neighbours of the new vector (hnswlib's updatePoint).
    g.addPoint(code.data(), slot);
  } else {
    if (g.cur_element_count == g.max_elements_) {
      g.resizeIndex(2 * g.max_elements_);
      exact_.resize(g.max_elements_ * dim_);
    }
    g.addPoint(code.data(), slot);
  }
  std::copy(vector, vector + dim_, exact_.begin() + static_cast<std::ptrdiff_t>(slot * dim_));
}

bool HnswIndex::RestoreVector(size_t slot, const float* vector) {
  if (slot >= graph_->cur_element_count) return false;
  const std::vector<char> code = Encode(vector, dim_);
  if (std::memcmp(code.data(), graph_->getDataByInternalId(static_cast<hnswlib::tableint>(slot)),
                  code.size()) != 0) {
    return false;
  }
  std::copy(vector, vector + dim_, exact_.begin() + static_cast<std::ptrdiff_t>(slot * dim_));
  return true;
}

void HnswIndex::MarkDeleted(size_t slot) { graph_->markDelete(slot); }

bool HnswIndex::IsDeleted(size_t slot) const {
  return graph_->isMarkedDeleted(static_cast<hnswlib::tableint>(slot));
}

std::vector<std::pair<float, size_t>> HnswIndex::Search(const float* query, size_t k) const {
  std::vector<std::pair<float, size_t>> result;
  if (graph_->cur_element_count == graph_->num_deleted_ || k == 0) return result;
  // All max(ef, k) candidates of the search over codes, re-ranked exactly.
  const std::vector<char> code = Encode(query, dim_);
  auto queue = graph_->searchKnn(code.data(), std::max(graph_->ef_, k));
  result.reserve(queue.size());
  for (; !queue.empty(); queue.pop()) {
    const size_t slot = queue.top().second;
    result.emplace_back(Dot(query, &exact_[slot * dim_], dim_), slot);
  }
  std::sort(result.begin(), result.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  if (result.size() > k) result.resize(k);
  return result;
}

void HnswIndex::SetEf(size_t ef) { graph_->setEf(ef); }

size_t HnswIndex::Slots() const { return graph_->cur_element_count; }
size_t HnswIndex::DeletedSlots() const { return graph_->num_deleted_; }
size_t HnswIndex::Capacity() const { return graph_->max_elements_; }

int64_t HnswIndex::MemoryBytes() const {
  const Graph& g = *graph_;
  const uint64_t capacity = g.max_elements_;
  uint64_t bytes = capacity * g.size_data_per_element_;  // level 0: links, code, label
  bytes += exact_.capacity() * sizeof(float);            // float vectors for re-ranking
  bytes += capacity * (sizeof(char*) + sizeof(int) + sizeof(std::mutex));
  bytes += uint64_t{Graph::max_update_element_locks} * sizeof(std::mutex);
  // One visited list; each concurrent search may add another.
  bytes += capacity * sizeof(hnswlib::vl_type);
  bytes += uint64_t{g.cur_element_count} * 48;  // label_lookup_ hash node + bucket, approx.
  for (size_t i = 0; i < g.cur_element_count; ++i) {
    if (g.element_levels_[i] > 0) {
      bytes += uint64_t{g.size_links_per_element_} * g.element_levels_[i];
    }
  }
  return static_cast<int64_t>(bytes);
}

}  // namespace ag::internal
