#include "ground_server/place_db/place_db.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include "common/config/options.h"
#include "common/core/agent_name.h"
#include "ground_server/place_db/place_db_state.h"

namespace ag {

using internal::kNoId;
using internal::PlaceDbState;

namespace {

bool IsAgentName(const std::string& name) {
  return name.size() <= internal::kMaxAgentNameLength && IsValidAgentName(name);
}

/// Why a keyframe's own fields cannot be stored, or empty.
std::string KeyframeProblem(const AirKeyframe& keyframe) {
  if (!IsAgentName(keyframe.agent)) {
    return "agent name '" + keyframe.agent + "' must match [a-z0-9_]+ (1 to " +
           std::to_string(internal::kMaxAgentNameLength) + " characters)";
  }
  const Eigen::Matrix4d T = keyframe.T_wa_c.matrix();
  if (!T.allFinite() || !IsRotation(T.topLeftCorner<3, 3>(), 1e-3)) {
    return "T_wa_c is not a rigid transform (non-finite values or a rotation that is not "
           "orthonormal)";
  }
  const LocalFeatures& f = keyframe.features;
  if (!f.scores.empty() && f.scores.size() != f.keypoints.size()) {
    return std::to_string(f.scores.size()) + " keypoint scores for " +
           std::to_string(f.keypoints.size()) + " keypoints";
  }
  if (!f.descriptors.empty()) {
    if (f.descriptors.dims != 2) return "local descriptors must be a 2-D matrix";
    if (static_cast<size_t>(f.descriptors.rows) != f.keypoints.size()) {
      return "local descriptors have " + std::to_string(f.descriptors.rows) + " rows for " +
             std::to_string(f.keypoints.size()) + " keypoints";
    }
  }
  return {};
}

const char* InsertStatusName(PlaceDb::InsertStatus status) {
  switch (status) {
    case PlaceDb::InsertStatus::kInserted:
      return "inserted";
    case PlaceDb::InsertStatus::kBadDescriptor:
      return "bad global descriptor";
    case PlaceDb::InsertStatus::kBadKeyframe:
      return "bad keyframe";
    case PlaceDb::InsertStatus::kDuplicate:
      return "duplicate";
    case PlaceDb::InsertStatus::kTooLarge:
      return "too large";
  }
  return "?";
}

PlaceDb::InsertResult Rejected(PlaceDb::InsertStatus status, const AirKeyframe& keyframe,
                               const std::string& problem) {
  PlaceDb::InsertResult result;
  result.status = status;
  result.reason = std::string(InsertStatusName(status)) + ": keyframe (agent '" + keyframe.agent +
                  "', seq " + std::to_string(keyframe.seq) + ") rejected: " + problem;
  return result;
}

PlaceDb::Entry MakeEntry(PlaceDb::Id id, const std::shared_ptr<const AirKeyframe>& keyframe) {
  PlaceDb::Entry entry;
  entry.id = id;
  entry.agent = keyframe->agent;
  entry.seq = keyframe->seq;
  entry.t_ns = keyframe->t_ns;
  entry.T_wa_c = keyframe->T_wa_c;
  entry.keyframe = keyframe;
  return entry;
}

// ------------------------------------------------------------ thin-out costs

/// Recomputes the thin-out queue key of `id` from its current neighbours.
void UpdateThinCost(PlaceDbState::Agent& agent, PlaceDbState& state,
                    const PlaceDb::Options& options, PlaceDb::Id id) {
  PlaceDbState::Entry& entry = state.entries.at(id);
  if (entry.thin_cost >= 0) agent.thin_queue.erase({entry.thin_cost, id});
  entry.thin_cost = -1;
  const auto it = agent.by_seq.find(entry.keyframe->seq);
  if (it == agent.by_seq.begin() || std::next(it) == agent.by_seq.end()) return;
  const Pose& T = entry.keyframe->T_wa_c;
  const Pose& T_prev = state.entries.at(std::prev(it)->second).keyframe->T_wa_c;
  const Pose& T_next = state.entries.at(std::next(it)->second).keyframe->T_wa_c;
  const double w = options.thin_rotation_weight_m_per_rad;
  entry.thin_cost = std::min(internal::ThinGap(T, T_prev, w), internal::ThinGap(T, T_next, w));
  agent.thin_queue.insert({entry.thin_cost, id});
}

/// Recomputes the costs of the keyframes next to `it` (and of `it` itself
/// unless it is end()).
void UpdateThinNeighbourhood(PlaceDbState::Agent& agent, PlaceDbState& state,
                             const PlaceDb::Options& options,
                             std::map<int64_t, PlaceDb::Id>::iterator it) {
  if (it != agent.by_seq.begin()) UpdateThinCost(agent, state, options, std::prev(it)->second);
  if (it == agent.by_seq.end()) return;
  UpdateThinCost(agent, state, options, it->second);
  if (std::next(it) != agent.by_seq.end()) {
    UpdateThinCost(agent, state, options, std::next(it)->second);
  }
}

void Evict(PlaceDbState& state, const PlaceDb::Options& options, PlaceDb::Id id) {
  PlaceDbState::Entry& entry = state.entries.at(id);
  PlaceDbState::Agent& agent = state.agents.at(entry.keyframe->agent);
  agent.graph->MarkDeleted(entry.slot);
  agent.slot_ids[entry.slot] = kNoId;
  agent.free_slots.push_back(entry.slot);
  if (entry.thin_cost >= 0) agent.thin_queue.erase({entry.thin_cost, id});
  const auto next = agent.by_seq.erase(agent.by_seq.find(entry.keyframe->seq));
  state.keyframe_bytes -= entry.bytes;
  state.entries.erase(id);
  // The neighbours now border each other: both costs change.
  if (next != agent.by_seq.end()) {
    UpdateThinNeighbourhood(agent, state, options, next);
  } else if (!agent.by_seq.empty()) {
    UpdateThinCost(agent, state, options, std::prev(next)->second);
  }
}

/// The keyframe to evict next (see Options::eviction), never `keep`.
PlaceDb::Id ChooseVictim(const PlaceDbState& state, const PlaceDb::Options& options,
                         PlaceDb::Id keep) {
  const auto kept = state.entries.find(keep);
  const std::string* keep_agent =
      kept == state.entries.end() ? nullptr : &kept->second.keyframe->agent;
  const PlaceDbState::Agent* chosen = nullptr;
  size_t chosen_size = 0;
  bool chosen_is_keep_agent = false;
  for (const auto& [name, agent] : state.agents) {
    const size_t size = agent.by_seq.size();
    const bool is_keep_agent = keep_agent != nullptr && name == *keep_agent;
    const size_t evictable = is_keep_agent ? size - 1 : size;
    if (evictable == 0) continue;
    // Most keyframes wins; on a tie prefer an agent other than the inserting one.
    if (chosen == nullptr || size > chosen_size ||
        (size == chosen_size && chosen_is_keep_agent && !is_keep_agent)) {
      chosen = &agent;
      chosen_size = size;
      chosen_is_keep_agent = is_keep_agent;
    }
  }
  if (chosen == nullptr) return kNoId;
  if (options.eviction == "thin") {
    for (const auto& [cost, id] : chosen->thin_queue) {
      if (id != keep) return id;
    }
  }
  for (const auto& [seq, id] : chosen->by_seq) {
    if (id != keep) return id;
  }
  return kNoId;
}

}  // namespace

// ------------------------------------------------------------------ internal

namespace internal {

std::vector<float> NormalisedDescriptor(const std::vector<float>& global, int dim,
                                        std::string* problem) {
  if (global.size() != static_cast<size_t>(dim)) {
    *problem = "global descriptor has " + std::to_string(global.size()) + " values, expected " +
               std::to_string(dim) + " (Options::dim)";
    return {};
  }
  double norm2 = 0;
  for (size_t i = 0; i < global.size(); ++i) {
    if (!std::isfinite(global[i])) {
      std::ostringstream text;
      text << "global descriptor value " << i << " is not finite (" << global[i] << ")";
      *problem = text.str();
      return {};
    }
    norm2 += double{global[i]} * global[i];
  }
  if (!(norm2 > 0) || !std::isfinite(norm2)) {
    *problem = "global descriptor has zero norm";
    return {};
  }
  const double scale = 1.0 / std::sqrt(norm2);
  std::vector<float> unit(global.size());
  for (size_t i = 0; i < global.size(); ++i) unit[i] = static_cast<float>(global[i] * scale);
  return unit;
}

double ThinGap(const Pose& a, const Pose& b, double rotation_weight_m_per_rad) {
  const double dp = (a.translation() - b.translation()).norm();
  const double angle = Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
  return dp + rotation_weight_m_per_rad * angle;
}

void RegisterEntry(PlaceDbState& state, const PlaceDb::Options& options, PlaceDb::Id id,
                   std::shared_ptr<const AirKeyframe> keyframe, size_t slot) {
  PlaceDbState::Agent& agent = state.agents.at(keyframe->agent);
  if (agent.slot_ids.size() <= slot) agent.slot_ids.resize(slot + 1, kNoId);
  agent.slot_ids[slot] = id;
  PlaceDbState::Entry entry;
  entry.bytes = KeyframeBytes(*keyframe);
  entry.slot = slot;
  const int64_t seq = keyframe->seq;
  entry.keyframe = std::move(keyframe);
  state.keyframe_bytes += entry.bytes;
  state.entries.emplace(id, std::move(entry));
  const auto it = agent.by_seq.emplace(seq, id).first;
  UpdateThinNeighbourhood(agent, state, options, it);
}

std::vector<PlaceDb::Id> EnforceCaps(PlaceDbState& state, const PlaceDb::Options& options,
                                     PlaceDb::Id keep) {
  std::vector<PlaceDb::Id> evicted;
  while (static_cast<int64_t>(state.entries.size()) > options.max_keyframes ||
         state.keyframe_bytes > options.max_bytes) {
    const PlaceDb::Id victim = ChooseVictim(state, options, keep);
    if (victim == kNoId) break;  // only `keep` is left, and Insert checked it fits
    Evict(state, options, victim);
    evicted.push_back(victim);
  }
  return evicted;
}

}  // namespace internal

// ------------------------------------------------------------------- PlaceDb

void PlaceDb::Options::Check() const {
  CheckOption(dim > 0, "dim", "must be > 0");
  // hnswlib keeps link counts in 16 bits with a delete flag in the third
  // byte; far below that, M above a few dozen only costs memory.
  CheckOption(hnsw_m >= 2 && hnsw_m <= 256, "hnsw_m", "must be in [2, 256]");
  CheckOption(ef_construction >= 1, "ef_construction", "must be >= 1");
  CheckOption(ef_search >= 1, "ef_search", "must be >= 1");
  CheckOption(initial_capacity >= 1, "initial_capacity", "must be >= 1");
  CheckOption(max_keyframes >= 1, "max_keyframes", "must be >= 1");
  CheckOption(max_bytes >= 1, "max_bytes", "must be >= 1");
  CheckOption(eviction == "thin" || eviction == "oldest", "eviction",
              "must be \"thin\" or \"oldest\" (is \"" + eviction + "\")");
  CheckOption(std::isfinite(thin_rotation_weight_m_per_rad) && thin_rotation_weight_m_per_rad >= 0,
              "thin_rotation_weight_m_per_rad", "must be finite and >= 0");
}

int64_t KeyframeBytes(const AirKeyframe& keyframe) {
  const LocalFeatures& f = keyframe.features;
  int64_t bytes = sizeof(AirKeyframe);
  bytes += static_cast<int64_t>(keyframe.agent.size() + keyframe.camera_id.size() +
                                f.descriptor_type.size());
  bytes += static_cast<int64_t>(f.keypoints.size() * sizeof(Eigen::Vector2f));
  bytes += static_cast<int64_t>(f.scores.size() * sizeof(float));
  bytes += static_cast<int64_t>(f.descriptors.total() * f.descriptors.elemSize());
  bytes += static_cast<int64_t>(keyframe.global_descriptor.size() * sizeof(float));
  return bytes;
}

PlaceDb::PlaceDb() : PlaceDb(Options()) {}

PlaceDb::PlaceDb(Options options)
    : options_(std::move(options)), state_(std::make_unique<PlaceDbState>()) {
  CheckOptions(options_);
}

PlaceDb::~PlaceDb() = default;

PlaceDb::InsertResult PlaceDb::Insert(AirKeyframe keyframe) {
  std::string problem;
  std::vector<float> unit =
      internal::NormalisedDescriptor(keyframe.global_descriptor, options_.dim, &problem);
  if (unit.empty()) return Rejected(InsertStatus::kBadDescriptor, keyframe, problem);
  problem = KeyframeProblem(keyframe);
  if (!problem.empty()) return Rejected(InsertStatus::kBadKeyframe, keyframe, problem);
  const int64_t bytes = KeyframeBytes(keyframe);
  if (bytes > options_.max_bytes) {
    return Rejected(
        InsertStatus::kTooLarge, keyframe,
        std::to_string(bytes) + " bytes exceed max_bytes = " + std::to_string(options_.max_bytes));
  }
  // The database hands out const views of the keyframe; it must not share
  // the pixel buffer of the local descriptors with the caller's cv::Mat.
  keyframe.features.descriptors = keyframe.features.descriptors.clone();

  std::unique_lock lock(mutex_);
  PlaceDbState& state = *state_;
  auto agent_it = state.agents.find(keyframe.agent);
  if (agent_it != state.agents.end()) {
    const auto dup = agent_it->second.by_seq.find(keyframe.seq);
    if (dup != agent_it->second.by_seq.end()) {
      return Rejected(InsertStatus::kDuplicate, keyframe,
                      "already in the database as id " + std::to_string(dup->second));
    }
  } else {
    PlaceDbState::Agent agent;
    agent.graph = std::make_unique<internal::HnswIndex>(
        options_.dim, options_.hnsw_m, options_.ef_construction,
        static_cast<size_t>(options_.initial_capacity),
        static_cast<unsigned>(options_.random_seed));
    agent.graph->SetEf(static_cast<size_t>(options_.ef_search));
    agent_it = state.agents.emplace(keyframe.agent, std::move(agent)).first;
  }
  PlaceDbState::Agent& agent = agent_it->second;
  size_t slot = agent.slot_ids.size();
  if (!agent.free_slots.empty()) slot = agent.free_slots.back();
  agent.graph->Put(slot, unit.data());
  if (slot != agent.slot_ids.size()) agent.free_slots.pop_back();

  const Id id = state.next_id++;
  internal::RegisterEntry(state, options_, id,
                          std::make_shared<const AirKeyframe>(std::move(keyframe)), slot);
  InsertResult result;
  result.success = true;
  result.status = InsertStatus::kInserted;
  result.id = id;
  result.evicted = internal::EnforceCaps(state, options_, id);
  return result;
}

PlaceDb::QueryResult PlaceDb::Query(const std::vector<float>& global, int k,
                                    const std::optional<std::string>& agent) const {
  QueryResult result;
  if (k < 1) {
    result.reason = "query rejected: k = " + std::to_string(k) + " must be >= 1";
    return result;
  }
  std::string problem;
  const std::vector<float> unit = internal::NormalisedDescriptor(global, options_.dim, &problem);
  if (unit.empty()) {
    result.reason = "query rejected: " + problem;
    return result;
  }

  std::shared_lock lock(mutex_);
  const PlaceDbState& state = *state_;
  auto search = [&](const PlaceDbState::Agent& a) {
    for (const auto& [similarity, slot] : a.graph->Search(unit.data(), static_cast<size_t>(k))) {
      const Id id = a.slot_ids.at(slot);
      const PlaceDbState::Entry& entry = state.entries.at(id);
      result.matches.push_back({MakeEntry(id, entry.keyframe), similarity});
    }
  };
  if (agent) {
    const auto it = state.agents.find(*agent);
    if (it != state.agents.end()) search(it->second);
  } else {
    for (const auto& [name, a] : state.agents) search(a);
  }
  lock.unlock();

  std::sort(result.matches.begin(), result.matches.end(), [](const Match& a, const Match& b) {
    return a.similarity != b.similarity ? a.similarity > b.similarity : a.entry.id < b.entry.id;
  });
  if (result.matches.size() > static_cast<size_t>(k)) result.matches.resize(static_cast<size_t>(k));
  result.success = true;
  return result;
}

std::shared_ptr<const AirKeyframe> PlaceDb::Get(Id id) const {
  std::shared_lock lock(mutex_);
  const auto it = state_->entries.find(id);
  return it == state_->entries.end() ? nullptr : it->second.keyframe;
}

std::optional<PlaceDb::Entry> PlaceDb::GetEntry(Id id) const {
  std::shared_lock lock(mutex_);
  const auto it = state_->entries.find(id);
  if (it == state_->entries.end()) return std::nullopt;
  return MakeEntry(id, it->second.keyframe);
}

std::vector<PlaceDb::Id> PlaceDb::Ids(const std::optional<std::string>& agent) const {
  std::vector<Id> ids;
  std::shared_lock lock(mutex_);
  for (const auto& [name, a] : state_->agents) {
    if (agent && name != *agent) continue;
    for (const auto& [seq, id] : a.by_seq) ids.push_back(id);
  }
  lock.unlock();
  std::sort(ids.begin(), ids.end());
  return ids;
}

int64_t PlaceDb::Size() const {
  std::shared_lock lock(mutex_);
  return static_cast<int64_t>(state_->entries.size());
}

PlaceDb::Stats PlaceDb::GetStats() const {
  std::shared_lock lock(mutex_);
  Stats stats;
  stats.keyframes = static_cast<int64_t>(state_->entries.size());
  stats.agents = static_cast<int64_t>(state_->agents.size());
  stats.keyframe_bytes = state_->keyframe_bytes;
  stats.index_bytes = stats.keyframes * internal::kEntryOverheadBytes;
  for (const auto& [name, a] : state_->agents) {
    stats.graph_slots += static_cast<int64_t>(a.graph->Slots());
    stats.deleted_slots += static_cast<int64_t>(a.graph->DeletedSlots());
    stats.index_bytes +=
        a.graph->MemoryBytes() + static_cast<int64_t>(a.slot_ids.capacity() * sizeof(Id) +
                                                      a.free_slots.capacity() * sizeof(size_t));
  }
  return stats;
}

PlaceDb::Options PlaceDb::GetOptions() const {
  std::shared_lock lock(mutex_);
  return options_;
}

void PlaceDb::SetEfSearch(int ef_search) {
  CheckOption(ef_search >= 1, "ef_search", "must be >= 1");
  std::unique_lock lock(mutex_);
  options_.ef_search = ef_search;
  for (auto& [name, a] : state_->agents) a.graph->SetEf(static_cast<size_t>(ef_search));
}

}  // namespace ag
