#pragma once

// The ground side's place database of UAV keyframes.
//
// Paper, Sec. "Database Maintenance and Retrieval": the UGV inserts every
// global descriptor (MixVPR) received from a UAV into an incremental HNSW
// graph and, for each of its own keyframes, retrieves the most similar UAV
// keyframes; the full keyframes (keypoints, local descriptors, pose) are kept
// so that a UGV frame can be matched against a UAV frame sent minutes earlier.
//
// Design:
// - one HNSW graph per air agent (hnswlib, inner product on L2-normalised
//   vectors = cosine similarity). The estimator works per UAV world, so the
//   common query is filtered by agent and is served by that agent's graph
//   alone; an unfiltered query searches every graph and merges.
// - the graph navigates on int8 codes of the descriptors (4x fewer bytes per
//   visited node: queries are memory-bound once the graph outgrows the
//   cache) and re-ranks its ef candidates with the float descriptors, so
//   similarities are exact cosines and recall is that of the graph search.
// - graphs grow by doubling their capacity (no rebuild). An evicted keyframe
//   is marked deleted in its graph and its slot is refilled by the agent's
//   next keyframe, so the graph never holds more slots than the agent's peak.
// - memory is bounded by Options::max_keyframes and Options::max_bytes; see
//   Options::eviction for which keyframe goes.
// - Save/Load write a versioned, checksummed snapshot atomically (see Save).

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/geometry/pose.h"
#include "common/types/keyframe.h"

namespace ag {

namespace internal {
struct PlaceDbState;
}  // namespace internal

/// Place database: HNSW retrieval over UAV keyframes' global descriptors,
/// with the full keyframes kept under a memory cap.
///
/// Thread safety: every method may be called from any thread. Insert,
/// SetEfSearch and Load take an exclusive lock (one writer at a time;
/// readers wait for it). Query, Get, GetEntry, Ids, Size and GetStats take a
/// shared lock and run concurrently with each other. Save holds the shared
/// lock only while it writes the graphs and collects the keyframe list, then
/// writes the keyframes without the lock; concurrent Saves are serialised.
/// Keyframes are handed out as shared_ptr<const AirKeyframe>: immutable and
/// still valid after the database evicts them.
class PlaceDb {
 public:
  /// Database-wide keyframe id: assigned by Insert, increasing, never reused
  /// (also not across Save/Load).
  using Id = int64_t;

  struct Options {
    int dim = 512;              ///< global descriptor length (floats)
    int hnsw_m = 16;            ///< HNSW links per node and layer (level 0: 2x)
    int ef_construction = 200;  ///< HNSW candidate list size while inserting
    /// HNSW candidate list size while querying (max(ef_search, k) is used).
    /// 32: recall@1 >= 0.99 of exact search up to ~20k trajectory-like
    /// entries at < 0.1 ms per query (tools/bench/place_db_bench).
    int ef_search = 32;
    int initial_capacity = 1024;     ///< slots first allocated per agent graph; doubles when full
    int64_t max_keyframes = 20000;   ///< cap on retained keyframes, all agents together
    int64_t max_bytes = 2000000000;  ///< cap on retained keyframe memory (bytes, KeyframeBytes)
    /// Which keyframe goes when a cap is exceeded. Always from the agent
    /// holding the most keyframes (ties: not the inserting agent, then by
    /// name). Within it:
    ///  "thin":   the keyframe closest in pose to one of its neighbours in
    ///            sequence order (first and last never), so dense stretches
    ///            (hovering, slow flight) thin out while the covered area is
    ///            kept; an agent with fewer than 3 keyframes loses its oldest;
    ///  "oldest": the keyframe with the lowest sequence number.
    std::string eviction = "thin";
    double thin_rotation_weight_m_per_rad = 2.0;  ///< pose gap = |dp| + w * angle (m per rad)
    int random_seed = 100;  ///< seed of HNSW's level generator (reproducible graphs)

    template <class V>
    void VisitFields(V& v) {
      v("dim", dim);
      v("hnsw_m", hnsw_m);
      v("ef_construction", ef_construction);
      v("ef_search", ef_search);
      v("initial_capacity", initial_capacity);
      v("max_keyframes", max_keyframes);
      v("max_bytes", max_bytes);
      v("eviction", eviction);
      v("thin_rotation_weight_m_per_rad", thin_rotation_weight_m_per_rad);
      v("random_seed", random_seed);
    }
    void Check() const;
  };

  /// What the database knows about one retained keyframe.
  struct Entry {
    Id id = -1;
    std::string agent;
    int64_t seq = 0;
    int64_t t_ns = 0;                ///< image time in the air clock (ns)
    Pose T_wa_c = Pose::Identity();  ///< camera pose in the agent's world
    /// The full keyframe as inserted (global descriptor as received).
    std::shared_ptr<const AirKeyframe> keyframe;
  };

  struct Match {
    Entry entry;
    float similarity = 0;  ///< cosine similarity with the query, in [-1, 1]
  };

  enum class InsertStatus {
    kInserted,
    kBadDescriptor,  ///< global descriptor of the wrong length, non-finite or zero
    kBadKeyframe,    ///< keyframe fields inconsistent (agent name, pose, features)
    kDuplicate,      ///< this (agent, seq) is already in the database
    kTooLarge,       ///< the keyframe alone exceeds Options::max_bytes
  };

  struct InsertResult {
    bool success = false;
    InsertStatus status = InsertStatus::kBadKeyframe;
    std::string reason;       ///< why it was rejected (empty on success)
    Id id = -1;               ///< the new keyframe's id on success
    std::vector<Id> evicted;  ///< keyframes dropped to respect the caps
  };

  struct QueryResult {
    bool success = false;
    std::string reason;          ///< why the query was rejected (empty on success)
    std::vector<Match> matches;  ///< most similar first (ties: lower id first)
  };

  struct SaveResult {
    bool success = false;
    std::string reason;         ///< what failed (the previous snapshot is intact)
    std::string snapshot_dir;   ///< the directory the snapshot was written to
    int64_t keyframes = 0;      ///< keyframes in the snapshot
    int64_t bytes_written = 0;  ///< all snapshot files together
  };

  struct Stats {
    int64_t keyframes = 0;       ///< retained keyframes
    int64_t agents = 0;          ///< agents with a graph (including ones fully evicted)
    int64_t graph_slots = 0;     ///< filled HNSW slots, live + deleted, all agents
    int64_t deleted_slots = 0;   ///< slots of evicted keyframes, waiting to be refilled
    int64_t keyframe_bytes = 0;  ///< sum of KeyframeBytes of retained keyframes
    int64_t index_bytes = 0;     ///< HNSW graphs + bookkeeping, estimate
    int64_t TotalBytes() const { return keyframe_bytes + index_bytes; }
  };

  /// An empty database with default options.
  PlaceDb();
  /// Throws OptionError when `options` fail Check().
  explicit PlaceDb(Options options);
  ~PlaceDb();
  PlaceDb(const PlaceDb&) = delete;
  PlaceDb& operator=(const PlaceDb&) = delete;

  /// Adds a keyframe and then evicts others until the caps hold again. The
  /// global descriptor must have Options::dim finite values and a non-zero
  /// norm; the graph indexes it L2-normalised. A rejected keyframe changes
  /// nothing. Cost: one HNSW insertion (slot refill when evicting).
  InsertResult Insert(AirKeyframe keyframe);

  /// The k keyframes whose global descriptors are most similar (cosine) to
  /// `global`, of `agent` only when given (an unknown agent gives no
  /// matches). Fails (success false) on a wrong length, non-finite values,
  /// zero norm or k < 1. Approximate: HNSW with Options::ef_search.
  QueryResult Query(const std::vector<float>& global, int k,
                    const std::optional<std::string>& agent = std::nullopt) const;

  /// The keyframe with this id, or nullptr when unknown or evicted.
  std::shared_ptr<const AirKeyframe> Get(Id id) const;
  /// Its metadata, or nullopt when unknown or evicted.
  std::optional<Entry> GetEntry(Id id) const;
  /// Ids of retained keyframes (of `agent` only when given), ascending.
  std::vector<Id> Ids(const std::optional<std::string>& agent = std::nullopt) const;
  /// Number of retained keyframes.
  int64_t Size() const;
  Stats GetStats() const;
  /// Options in effect (ef_search as last set).
  Options GetOptions() const;
  /// Changes the query candidate list size (>= 1) for all later queries.
  void SetEfSearch(int ef_search);

  /// Writes a snapshot to directory `dir` (created if missing) atomically:
  /// everything goes into a new sibling `dir/snap-<generation>/`, each file
  /// and the directory are fsynced, then `dir/CURRENT` (naming the snapshot)
  /// is replaced by an fsynced rename; only then are older snapshots removed.
  /// A crash at any point leaves `dir` loading as the previous or the new
  /// state, never a mix. Files of a snapshot:
  ///   manifest.bin   magic "AGPDBMF\0", version, dim, generation, next id,
  ///                  keyframe count, per agent (name, graph file, its size
  ///                  and CRC-32), keyframes.bin's size and CRC-32; CRC-32.
  ///   graph_<i>.hnsw hnswlib's saveIndex of agent i's graph (int8 codes,
  ///                  labels = slots, evicted slots marked deleted).
  ///   keyframes.bin  magic "AGPDBKF\0", version, dim, count, one record per
  ///                  keyframe (id, slot and every AirKeyframe field); CRC-32.
  ///                  Load re-derives each slot's float vector from the
  ///                  record and checks it against the slot's code.
  /// All integers little-endian. Failures (disk full, permissions) come back
  /// in the result; the previous snapshot stays the loadable one.
  SaveResult Save(const std::string& dir) const;

  /// Replaces the whole content by the snapshot in `dir` (as written by
  /// Save), then applies this database's caps (evicting as Insert would).
  /// Keeps this database's options; the graphs keep the M and
  /// ef_construction they were built with. Throws InputError naming the file
  /// and problem (kMissingFile: no snapshot; kMalformedRow: truncated or
  /// corrupt, checksum mismatch, inconsistent records; kBadValue: unsupported
  /// version or another descriptor dimension) and then leaves the database
  /// exactly as it was.
  void Load(const std::string& dir);

 private:
  Options options_;
  mutable std::shared_mutex mutex_;
  mutable std::mutex save_mutex_;
  std::unique_ptr<internal::PlaceDbState> state_;
};

/// Estimated heap bytes of one retained keyframe (what max_bytes counts):
/// the struct, its strings, keypoints, scores, local and global descriptors.
int64_t KeyframeBytes(const AirKeyframe& keyframe);

}  // namespace ag
