// PlaceDb::Save and PlaceDb::Load: the snapshot format and its atomic commit
// (layout documented at PlaceDb::Save).

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>
#include <utility>

#include "ground_server/place_db/binary_io.h"
#include "ground_server/place_db/place_db.h"
#include "ground_server/place_db/place_db_state.h"

namespace ag {

namespace fs = std::filesystem;

using internal::FileReader;
using internal::FileWriter;
using internal::kNoId;
using internal::PlaceDbState;
using internal::SnapshotReadError;

namespace {

constexpr char kManifestMagic[8] = {'A', 'G', 'P', 'D', 'B', 'M', 'F', '\0'};
constexpr char kKeyframesMagic[8] = {'A', 'G', 'P', 'D', 'B', 'K', 'F', '\0'};
/// Bump on any layout change; Load rejects versions it does not know.
constexpr uint32_t kFormatVersion = 1;
constexpr char kCurrentFile[] = "CURRENT";
constexpr char kSnapshotPrefix[] = "snap-";
constexpr char kManifestFile[] = "manifest.bin";
constexpr char kKeyframesFile[] = "keyframes.bin";
constexpr size_t kMaxStringBytes = 4096;

std::string SnapshotName(int64_t generation) {
  std::string digits = std::to_string(generation);
  if (digits.size() < 12) digits.insert(0, 12 - digits.size(), '0');
  return kSnapshotPrefix + digits;
}

/// The generation of a "snap-<digits>" name, or -1.
int64_t SnapshotGeneration(const std::string& name) {
  const size_t prefix = std::strlen(kSnapshotPrefix);
  if (name.size() <= prefix || name.size() > prefix + 18 ||
      name.compare(0, prefix, kSnapshotPrefix) != 0) {
    return -1;
  }
  int64_t generation = 0;
  for (size_t i = prefix; i < name.size(); ++i) {
    if (name[i] < '0' || name[i] > '9') return -1;
    generation = generation * 10 + (name[i] - '0');
  }
  return generation;
}

struct GraphFile {
  std::string agent;
  std::string file;
  uint64_t slots = 0;
  uint64_t live = 0;
  internal::FileDigest digest;
};

struct Record {
  PlaceDb::Id id = 0;
  size_t slot = 0;
  std::shared_ptr<const AirKeyframe> keyframe;
};

// ------------------------------------------------------------------ writing

void WriteRecord(FileWriter& out, const Record& record) {
  const AirKeyframe& kf = *record.keyframe;
  out.Pod<int64_t>(record.id);
  out.String(kf.agent);
  out.Pod<int64_t>(kf.seq);
  out.Pod<int64_t>(kf.t_ns);
  out.String(kf.camera_id);
  const Eigen::Matrix3d R = kf.T_wa_c.linear();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.Pod<double>(R(r, c));
  }
  for (int i = 0; i < 3; ++i) out.Pod<double>(kf.T_wa_c.translation()(i));
  out.Pod<uint64_t>(record.slot);
  const LocalFeatures& f = kf.features;
  out.Pod<uint32_t>(static_cast<uint32_t>(f.keypoints.size()));
  for (const Eigen::Vector2f& p : f.keypoints) {
    out.Pod<float>(p.x());
    out.Pod<float>(p.y());
  }
  out.Pod<uint32_t>(static_cast<uint32_t>(f.scores.size()));
  out.Write(f.scores.data(), f.scores.size() * sizeof(float));
  const cv::Mat& d = f.descriptors;
  out.Pod<int32_t>(d.empty() ? 0 : d.rows);
  out.Pod<int32_t>(d.empty() ? 0 : d.cols);
  out.Pod<int32_t>(d.type());
  for (int r = 0; !d.empty() && r < d.rows; ++r) out.Write(d.ptr(r), d.cols * d.elemSize());
  out.String(f.descriptor_type);
  out.Pod<uint32_t>(static_cast<uint32_t>(kf.global_descriptor.size()));
  out.Write(kf.global_descriptor.data(), kf.global_descriptor.size() * sizeof(float));
}

// ------------------------------------------------------------------ reading

InputError Corrupt(const std::string& file, const std::string& problem) {
  return InputError(InputErrorKind::kMalformedRow, file, 0, problem);
}

void ExpectMagic(FileReader& in, const char (&magic)[8], const char* what) {
  char read[8];
  in.Read(read, sizeof(read));
  if (std::memcmp(read, magic, sizeof(read)) != 0) {
    in.Fail(std::string("not a place database ") + what + " (bad magic)");
  }
}

void ExpectVersionAndDim(FileReader& in, int dim) {
  const auto version = in.Pod<uint32_t>();
  if (version != kFormatVersion) {
    throw InputError(InputErrorKind::kBadValue, in.Path(), 0,
                     "snapshot format version " + std::to_string(version) +
                         " is not supported (this build reads version " +
                         std::to_string(kFormatVersion) + ")");
  }
  const auto file_dim = in.Pod<uint32_t>();
  if (file_dim != static_cast<uint32_t>(dim)) {
    throw InputError(InputErrorKind::kBadValue, in.Path(), 0,
                     "snapshot holds " + std::to_string(file_dim) +
                         "-D global descriptors, this database is configured for " +
                         std::to_string(dim) + " (Options::dim)");
  }
}

/// Reads one keyframe record; structural problems throw SnapshotReadError.
Record ReadRecord(FileReader& in) {
  Record record;
  auto kf = std::make_shared<AirKeyframe>();
  record.id = in.Pod<int64_t>();
  kf->agent = in.String(internal::kMaxAgentNameLength);
  kf->seq = in.Pod<int64_t>();
  kf->t_ns = in.Pod<int64_t>();
  kf->camera_id = in.String(kMaxStringBytes);
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R(r, c) = in.Pod<double>();
  }
  Eigen::Vector3d t;
  for (int i = 0; i < 3; ++i) t(i) = in.Pod<double>();
  kf->T_wa_c = Pose::Identity();
  kf->T_wa_c.linear() = R;
  kf->T_wa_c.translation() = t;
  record.slot = static_cast<size_t>(in.Pod<uint64_t>());
  LocalFeatures& f = kf->features;
  f.keypoints.resize(in.Count(2 * sizeof(float)));
  for (Eigen::Vector2f& p : f.keypoints) {
    p.x() = in.Pod<float>();
    p.y() = in.Pod<float>();
  }
  f.scores.resize(in.Count(sizeof(float)));
  in.Read(f.scores.data(), f.scores.size() * sizeof(float));
  const auto rows = in.Pod<int32_t>();
  const auto cols = in.Pod<int32_t>();
  const auto type = in.Pod<int32_t>();
  if (rows < 0 || cols < 0 || type < 0 || CV_MAT_DEPTH(type) > CV_16F || CV_MAT_CN(type) > 4) {
    in.Fail("corrupt local descriptor header (rows " + std::to_string(rows) + ", cols " +
            std::to_string(cols) + ", type " + std::to_string(type) + ")");
  }
  const uint64_t desc_bytes =
      uint64_t{static_cast<uint32_t>(rows)} * static_cast<uint32_t>(cols) * CV_ELEM_SIZE(type);
  if (desc_bytes > in.Remaining()) in.Fail("truncated local descriptors");
  if (rows > 0 && cols > 0) {
    f.descriptors.create(rows, cols, type);
    in.Read(f.descriptors.data, desc_bytes);
  }
  f.descriptor_type = in.String(kMaxStringBytes);
  kf->global_descriptor.resize(in.Count(sizeof(float)));
  in.Read(kf->global_descriptor.data(), kf->global_descriptor.size() * sizeof(float));
  record.keyframe = std::move(kf);
  return record;
}

std::string ReadCurrent(const fs::path& dir) {
  const std::string path = (dir / kCurrentFile).string();
  FileReader in(path);
  if (in.Size() > 64) in.Fail("not a snapshot pointer (too long)");
  std::string text(static_cast<size_t>(in.Size()), '\0');
  in.Read(text.data(), text.size());
  if (!text.empty() && text.back() == '\n') text.pop_back();
  if (SnapshotGeneration(text) < 0) {
    throw Corrupt(path, "does not name a snapshot ('snap-<number>'): '" + text + "'");
  }
  return text;
}

/// Reads the snapshot `dir`/CURRENT points to into `state` (fresh). Throws
/// InputError or SnapshotReadError.
void ReadSnapshot(const fs::path& dir, const PlaceDb::Options& options, PlaceDbState& state) {
  if (!fs::is_directory(dir)) {
    throw InputError(InputErrorKind::kMissingFile, dir.string(), 0,
                     "no place database snapshot here (not a directory)");
  }
  if (!fs::exists(dir / kCurrentFile)) {
    throw InputError(InputErrorKind::kMissingFile, (dir / kCurrentFile).string(), 0,
                     "no place database snapshot here (CURRENT is missing)");
  }
  const fs::path snap = dir / ReadCurrent(dir);

  // Manifest: what the snapshot holds and the digests of its other files.
  FileReader manifest((snap / kManifestFile).string());
  ExpectMagic(manifest, kManifestMagic, "manifest");
  ExpectVersionAndDim(manifest, options.dim);
  manifest.Pod<uint64_t>();  // generation, informational (the directory name is authoritative)
  const auto next_id = manifest.Pod<int64_t>();
  const auto keyframe_count = manifest.Pod<uint64_t>();
  const uint32_t agent_count = manifest.Count(16);
  std::vector<GraphFile> graphs(agent_count);
  for (GraphFile& g : graphs) {
    g.agent = manifest.String(internal::kMaxAgentNameLength);
    g.file = manifest.String(kMaxStringBytes);
    g.slots = manifest.Pod<uint64_t>();
    g.live = manifest.Pod<uint64_t>();
    g.digest.size = manifest.Pod<uint64_t>();
    g.digest.crc = manifest.Pod<uint32_t>();
  }
  internal::FileDigest keyframes_digest;
  keyframes_digest.size = manifest.Pod<uint64_t>();
  keyframes_digest.crc = manifest.Pod<uint32_t>();
  manifest.ExpectCrc();
  manifest.ExpectEnd();
  if (next_id < 0) throw Corrupt(manifest.Path(), "negative next id");

  auto check_digest = [](const std::string& path, const internal::FileDigest& expected,
                         const internal::FileDigest& actual) {
    if (actual.size != expected.size) {
      throw Corrupt(path, "has " + std::to_string(actual.size) + " bytes, the manifest says " +
                              std::to_string(expected.size) + " (truncated or replaced)");
    }
    if (actual.crc != expected.crc) {
      throw Corrupt(path, "checksum mismatch with the manifest: the file is corrupt");
    }
  };

  // Graphs: checksum first, so hnswlib only ever parses intact files.
  for (const GraphFile& g : graphs) {
    if (g.file.find('/') != std::string::npos || g.file.empty() || g.file[0] == '.') {
      throw Corrupt(manifest.Path(), "bad graph file name '" + g.file + "'");
    }
    if (state.agents.count(g.agent) != 0) {
      throw Corrupt(manifest.Path(), "agent '" + g.agent + "' listed twice");
    }
    const std::string path = (snap / g.file).string();
    check_digest(path, g.digest, internal::DigestFile(path));
    PlaceDbState::Agent agent;
    try {
      agent.graph = internal::HnswIndex::Load(path, options.dim);
    } catch (const std::runtime_error& e) {
      throw Corrupt(path, e.what());
    }
    if (agent.graph->Slots() != g.slots ||
        agent.graph->Slots() - agent.graph->DeletedSlots() != g.live) {
      throw Corrupt(path, "graph has " + std::to_string(agent.graph->Slots()) + " slots (" +
                              std::to_string(agent.graph->DeletedSlots()) +
                              " deleted), the manifest says " + std::to_string(g.slots) + " (" +
                              std::to_string(g.slots - g.live) + " deleted)");
    }
    agent.graph->SetEf(static_cast<size_t>(options.ef_search));
    agent.slot_ids.assign(agent.graph->Slots(), kNoId);
    state.agents.emplace(g.agent, std::move(agent));
  }

  // Keyframes: full-file CRC against the manifest while parsing.
  const std::string keyframes_path = (snap / kKeyframesFile).string();
  FileReader in(keyframes_path);
  if (in.Size() != keyframes_digest.size) {
    check_digest(keyframes_path, keyframes_digest, {in.Size(), 0});
  }
  ExpectMagic(in, kKeyframesMagic, "keyframe file");
  ExpectVersionAndDim(in, options.dim);
  const auto count = in.Pod<uint64_t>();
  if (count != keyframe_count) {
    throw Corrupt(keyframes_path, "holds " + std::to_string(count) +
                                      " keyframes, the manifest says " +
                                      std::to_string(keyframe_count));
  }
  std::vector<Record> records;
  records.reserve(static_cast<size_t>(std::min<uint64_t>(count, in.Remaining() / 64)));
  for (uint64_t i = 0; i < count; ++i) records.push_back(ReadRecord(in));
  in.ExpectCrc();
  in.ExpectEnd();
  check_digest(keyframes_path, keyframes_digest, {in.Size(), in.Crc()});

  // Cross-checks, then registration.
  state.next_id = next_id;
  std::set<PlaceDb::Id> ids;
  for (const Record& r : records) {
    const std::string what = "keyframe id " + std::to_string(r.id) + ": ";
    if (r.id < 0 || r.id >= next_id || !ids.insert(r.id).second) {
      throw Corrupt(keyframes_path, what + "id out of range or repeated");
    }
    const auto agent_it = state.agents.find(r.keyframe->agent);
    if (agent_it == state.agents.end()) {
      throw Corrupt(keyframes_path, what + "agent '" + r.keyframe->agent + "' has no graph");
    }
    PlaceDbState::Agent& agent = agent_it->second;
    if (r.slot >= agent.slot_ids.size() || agent.slot_ids[r.slot] != kNoId ||
        agent.graph->IsDeleted(r.slot)) {
      throw Corrupt(keyframes_path, what + "slot " + std::to_string(r.slot) +
                                        " is out of range, repeated or deleted in the graph");
    }
    if (agent.by_seq.count(r.keyframe->seq) != 0) {
      throw Corrupt(keyframes_path,
                    what + "sequence number repeated for agent '" + r.keyframe->agent + "'");
    }
    std::string problem;
    const std::vector<float> unit =
        internal::NormalisedDescriptor(r.keyframe->global_descriptor, options.dim, &problem);
    if (unit.empty()) throw Corrupt(keyframes_path, what + problem);
    if (!agent.graph->RestoreVector(r.slot, unit.data())) {
      throw Corrupt(keyframes_path,
                    what + "global descriptor does not match its code in the graph");
    }
    internal::RegisterEntry(state, options, r.id, r.keyframe, r.slot);
  }
  for (auto& [name, agent] : state.agents) {
    // Every slot without a record must be a deleted one (counts matched above).
    for (size_t slot = agent.slot_ids.size(); slot-- > 0;) {
      if (agent.slot_ids[slot] == kNoId) agent.free_slots.push_back(slot);
    }
    if (agent.free_slots.size() != agent.graph->DeletedSlots()) {
      throw Corrupt(keyframes_path,
                    "agent '" + name + "': " + std::to_string(agent.by_seq.size()) +
                        " keyframes for " +
                        std::to_string(agent.graph->Slots() - agent.graph->DeletedSlots()) +
                        " live graph slots");
    }
  }
}

}  // namespace

PlaceDb::SaveResult PlaceDb::Save(const std::string& dir) const {
  std::lock_guard save_lock(save_mutex_);
  SaveResult result;
  fs::path snap;
  bool committed = false;
  try {
    const fs::path root(dir);
    fs::create_directories(root);
    // A generation above every snapshot present, committed or left over by
    // a crash, so a new snapshot never reuses a directory name.
    int64_t generation = 0;
    for (const auto& item : fs::directory_iterator(root)) {
      generation = std::max(generation, SnapshotGeneration(item.path().filename().string()));
    }
    ++generation;
    const std::string snap_name = SnapshotName(generation);
    snap = root / snap_name;
    fs::create_directory(snap);

    // Graphs and the keyframe list as one consistent cut, under the shared
    // lock; keyframes are immutable, so writing them needs no lock.
    std::vector<GraphFile> graphs;
    std::vector<Record> records;
    PlaceDb::Id next_id = 0;
    {
      std::shared_lock lock(mutex_);
      for (const auto& [name, agent] : state_->agents) {
        GraphFile g;
        g.agent = name;
        g.file = "graph_" + std::to_string(graphs.size()) + ".hnsw";
        g.slots = agent.graph->Slots();
        g.live = agent.graph->Slots() - agent.graph->DeletedSlots();
        agent.graph->Save((snap / g.file).string());
        graphs.push_back(std::move(g));
      }
      records.reserve(state_->entries.size());
      for (const auto& [id, entry] : state_->entries) {
        records.push_back({id, entry.slot, entry.keyframe});
      }
      next_id = state_->next_id;
    }
    std::sort(records.begin(), records.end(),
              [](const Record& a, const Record& b) { return a.id < b.id; });

    int64_t bytes = 0;
    for (GraphFile& g : graphs) {
      const std::string path = (snap / g.file).string();
      internal::SyncPath(path);
      g.digest = internal::DigestFile(path);
      bytes += static_cast<int64_t>(g.digest.size);
    }

    FileWriter keyframes((snap / kKeyframesFile).string());
    keyframes.Write(kKeyframesMagic, sizeof(kKeyframesMagic));
    keyframes.Pod<uint32_t>(kFormatVersion);
    keyframes.Pod<uint32_t>(static_cast<uint32_t>(options_.dim));
    keyframes.Pod<uint64_t>(records.size());
    for (const Record& r : records) WriteRecord(keyframes, r);
    keyframes.WriteCrc();
    keyframes.Close();
    bytes += static_cast<int64_t>(keyframes.Size());

    FileWriter manifest((snap / kManifestFile).string());
    manifest.Write(kManifestMagic, sizeof(kManifestMagic));
    manifest.Pod<uint32_t>(kFormatVersion);
    manifest.Pod<uint32_t>(static_cast<uint32_t>(options_.dim));
    manifest.Pod<uint64_t>(static_cast<uint64_t>(generation));
    manifest.Pod<int64_t>(next_id);
    manifest.Pod<uint64_t>(records.size());
    manifest.Pod<uint32_t>(static_cast<uint32_t>(graphs.size()));
    for (const GraphFile& g : graphs) {
      manifest.String(g.agent);
      manifest.String(g.file);
      manifest.Pod<uint64_t>(g.slots);
      manifest.Pod<uint64_t>(g.live);
      manifest.Pod<uint64_t>(g.digest.size);
      manifest.Pod<uint32_t>(g.digest.crc);
    }
    manifest.Pod<uint64_t>(keyframes.Size());
    manifest.Pod<uint32_t>(keyframes.Crc());
    manifest.WriteCrc();
    manifest.Close();
    bytes += static_cast<int64_t>(manifest.Size());
    internal::SyncPath(snap.string());
    internal::SyncPath(root.string());  // the snapshot's own entry, before CURRENT names it

    // Commit point: CURRENT names the new snapshot after an atomic rename.
    const fs::path pointer_tmp = root / (std::string(kCurrentFile) + ".tmp");
    fs::remove(pointer_tmp);
    {
      FileWriter pointer(pointer_tmp.string());
      const std::string text = snap_name + "\n";
      pointer.Write(text.data(), text.size());
      pointer.Close();
    }
    fs::rename(pointer_tmp, root / kCurrentFile);
    committed = true;
    result.snapshot_dir = snap.string();
    result.keyframes = static_cast<int64_t>(records.size());
    result.bytes_written = bytes;
    internal::SyncPath(root.string());  // makes the rename itself durable

    // Older snapshots (and crashed partial ones) are no longer reachable.
    std::error_code ec;
    for (fs::directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (name != snap_name && SnapshotGeneration(name) >= 0) {
        std::error_code ignored;
        fs::remove_all(it->path(), ignored);
      }
    }
    result.success = true;
  } catch (const std::exception& e) {
    result.reason = "saving the place database to " + dir + " failed: " + e.what();
    // Before the rename CURRENT still names the previous snapshot, so the
    // partial one is unreachable: drop it. After the rename the new snapshot
    // is the current one (complete, only possibly not yet durable): keep it.
    if (!committed && !snap.empty()) {
      std::error_code ignored;
      fs::remove_all(snap, ignored);
    }
  }
  return result;
}

void PlaceDb::Load(const std::string& dir) {
  const Options options = GetOptions();
  auto state = std::make_unique<PlaceDbState>();
  try {
    ReadSnapshot(fs::path(dir), options, *state);
  } catch (const SnapshotReadError& e) {
    throw InputError(e.Missing() ? InputErrorKind::kMissingFile : InputErrorKind::kMalformedRow,
                     e.File(), 0, e.what());
  } catch (const fs::filesystem_error& e) {
    throw InputError(InputErrorKind::kMissingFile, dir, 0, e.what());
  }
  internal::EnforceCaps(*state, options, kNoId);

  std::unique_lock lock(mutex_);
  for (auto& [name, agent] : state->agents)
    agent.graph->SetEf(static_cast<size_t>(options_.ef_search));
  state_.swap(state);
}

}  // namespace ag
