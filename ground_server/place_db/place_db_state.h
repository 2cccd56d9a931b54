#pragma once

// What a PlaceDb holds, shared by place_db.cc (insert, evict, query) and
// place_db_snapshot.cc (save, load). Internal: not part of the public API.

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "ground_server/place_db/hnsw_index.h"
#include "ground_server/place_db/place_db.h"

namespace ag::internal {

inline constexpr PlaceDb::Id kNoId = -1;

/// Longest agent name accepted (names travel in snapshots and logs).
inline constexpr size_t kMaxAgentNameLength = 64;

/// Bookkeeping bytes per entry beyond the keyframe itself (hash node,
/// ordered-map and set nodes, shared_ptr control block), an estimate.
inline constexpr int64_t kEntryOverheadBytes = 256;

struct PlaceDbState {
  struct Entry {
    std::shared_ptr<const AirKeyframe> keyframe;
    size_t slot = 0;        ///< slot in the agent's graph
    int64_t bytes = 0;      ///< KeyframeBytes(*keyframe)
    double thin_cost = -1;  ///< key in Agent::thin_queue, or < 0 when not queued
  };

  struct Agent {
    std::unique_ptr<HnswIndex> graph;
    std::vector<PlaceDb::Id> slot_ids;  ///< id per graph slot, kNoId when free
    std::vector<size_t> free_slots;     ///< deleted slots, refilled last-in first
    std::map<int64_t, PlaceDb::Id> by_seq;
    /// Keyframes with a neighbour on both sides in sequence order, keyed by
    /// the pose gap to the nearer one ("thin" eviction takes the front).
    std::set<std::pair<double, PlaceDb::Id>> thin_queue;
  };

  std::map<std::string, Agent> agents;
  std::unordered_map<PlaceDb::Id, Entry> entries;
  PlaceDb::Id next_id = 0;
  int64_t keyframe_bytes = 0;
};

/// Adds an entry whose vector is already in `agent.graph` at `slot`: ids,
/// sequence order, thin-out costs, byte count. No graph change.
void RegisterEntry(PlaceDbState& state, const PlaceDb::Options& options, PlaceDb::Id id,
                   std::shared_ptr<const AirKeyframe> keyframe, size_t slot);

/// Evicts keyframes until the caps of `options` hold; never `keep`.
/// Returns the evicted ids in eviction order.
std::vector<PlaceDb::Id> EnforceCaps(PlaceDbState& state, const PlaceDb::Options& options,
                                     PlaceDb::Id keep);

/// Checks a global descriptor and returns it L2-normalised, or an empty
/// vector with `problem` set. Deterministic: Load re-derives the graph's
/// vectors with it from the stored descriptors.
std::vector<float> NormalisedDescriptor(const std::vector<float>& global, int dim,
                                        std::string* problem);

/// Pose gap used by "thin" eviction: |p_a - p_b| + w * angle(R_a^T R_b).
double ThinGap(const Pose& a, const Pose& b, double rotation_weight_m_per_rad);

}  // namespace ag::internal
