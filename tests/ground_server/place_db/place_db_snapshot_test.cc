// Save/Load of the place database: round trip, corruption detection, and
// crash safety (a child process SIGKILLed while saving).

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "ground_server/place_db/binary_io.h"
#include "ground_server/place_db/place_db.h"
#include "ground_server/place_db/synthetic_places.h"
#include "tests/ground_server/place_db/place_db_test_util.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

const SyntheticPlaces& Places() {
  static const SyntheticPlaces places({});
  return places;
}

const std::vector<Pose>& Flight() {
  static const std::vector<Pose> flight = SyntheticFlight(20000, 2.0, 500.0, 21);
  return flight;
}

AirKeyframe Keyframe(const std::string& agent, int64_t seq) {
  return test::FlightKeyframe(Places(), Flight(), agent, seq, 16, 32);
}

/// A database with two agents and some evicted keyframes (deleted slots).
void Fill(PlaceDb& db, int per_agent) {
  for (int i = 0; i < per_agent; ++i) {
    ASSERT_TRUE(db.Insert(Keyframe("uav_a", i)).success);
    ASSERT_TRUE(db.Insert(Keyframe("uav_b", i)).success);
  }
}

PlaceDb::Options SmallCap(int64_t max_keyframes) {
  PlaceDb::Options options;
  options.max_keyframes = max_keyframes;
  return options;
}

/// Ids and similarities of the top 5 for some queries: a fingerprint of the
/// graph and the keyframes.
std::vector<std::pair<PlaceDb::Id, float>> Fingerprint(const PlaceDb& db) {
  std::vector<std::pair<PlaceDb::Id, float>> out;
  std::mt19937 rng(5);
  for (int i = 0; i < 40; ++i) {
    const auto q = db.Query(Places().Descriptor(Flight()[static_cast<size_t>(i) * 3], 0.5, rng), 5);
    for (const auto& m : q.matches) out.emplace_back(m.entry.id, m.similarity);
  }
  return out;
}

std::vector<std::string> Listing(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& item : fs::directory_iterator(dir)) names.push_back(item.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

std::string CurrentSnapshot(const std::string& dir) {
  std::ifstream in(dir + "/CURRENT");
  std::string name;
  std::getline(in, name);
  return dir + "/" + name;
}

void FlipByte(const std::string& path, uint64_t offset) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(static_cast<std::streamoff>(offset));
  char c = 0;
  f.read(&c, 1);
  c = static_cast<char>(c ^ 0x5A);
  f.seekp(static_cast<std::streamoff>(offset));
  f.write(&c, 1);
}

/// Loads `dir` into `db`, expecting failure; returns the error.
InputError LoadError(PlaceDb& db, const std::string& dir) {
  try {
    db.Load(dir);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "Load(" << dir << ") did not fail";
  return InputError(InputErrorKind::kBadValue, "", 0, "");
}

// ---------------------------------------------------------------- round trip

TEST(PlaceDbSnapshotTest, RoundTripRestoresEverything) {
  test::TempDir tmp;
  PlaceDb db(SmallCap(150));
  Fill(db, 100);  // 200 inserted, 50 evicted
  const auto saved = db.Save(tmp.path());
  ASSERT_TRUE(saved.success) << saved.reason;
  EXPECT_EQ(saved.keyframes, 150);
  EXPECT_GT(saved.bytes_written, 0);

  PlaceDb loaded(SmallCap(150));
  ASSERT_TRUE(loaded.Insert(Keyframe("uav_z", 0)).success);  // replaced by Load
  loaded.Load(tmp.path());
  EXPECT_EQ(loaded.Ids(), db.Ids());
  EXPECT_TRUE(loaded.Ids(std::string("uav_z")).empty());
  for (PlaceDb::Id id : db.Ids()) {
    const auto a = db.GetEntry(id);
    const auto b = loaded.GetEntry(id);
    ASSERT_TRUE(b.has_value());
    EXPECT_EQ(a->agent, b->agent);
    EXPECT_EQ(a->seq, b->seq);
    test::ExpectSameKeyframe(*a->keyframe, *b->keyframe);
  }
  EXPECT_EQ(Fingerprint(loaded), Fingerprint(db));
  const auto s1 = db.GetStats();
  const auto s2 = loaded.GetStats();
  EXPECT_EQ(s2.keyframes, s1.keyframes);
  EXPECT_EQ(s2.graph_slots, s1.graph_slots);
  EXPECT_EQ(s2.deleted_slots, s1.deleted_slots);
  EXPECT_EQ(s2.keyframe_bytes, s1.keyframe_bytes);

  // Ids continue after the saved ones, and the agent's free slots are reused.
  const auto r1 = db.Insert(Keyframe("uav_a", 500));
  const auto r2 = loaded.Insert(Keyframe("uav_a", 500));
  ASSERT_TRUE(r2.success);
  EXPECT_EQ(r2.id, r1.id);
  EXPECT_EQ(r2.evicted, r1.evicted);
  EXPECT_EQ(loaded.GetStats().graph_slots, s1.graph_slots);
  EXPECT_EQ(Fingerprint(loaded), Fingerprint(db));
}

TEST(PlaceDbSnapshotTest, LoadAppliesTheLoadingDatabasesCaps) {
  test::TempDir tmp;
  PlaceDb db;
  Fill(db, 40);
  ASSERT_TRUE(db.Save(tmp.path()).success);
  PlaceDb small(SmallCap(30));
  small.Load(tmp.path());
  EXPECT_EQ(small.Size(), 30);
  EXPECT_EQ(small.Ids(std::string("uav_a")).size(), 15U);
}

TEST(PlaceDbSnapshotTest, SavingAgainReplacesTheSnapshot) {
  test::TempDir tmp;
  PlaceDb db;
  Fill(db, 10);
  ASSERT_TRUE(db.Save(tmp.path()).success);
  const std::string first = CurrentSnapshot(tmp.path());
  Fill(db, 0);
  ASSERT_TRUE(db.Insert(Keyframe("uav_a", 10)).success);
  const auto second = db.Save(tmp.path());
  ASSERT_TRUE(second.success);
  EXPECT_NE(CurrentSnapshot(tmp.path()), first);
  EXPECT_EQ(second.snapshot_dir, CurrentSnapshot(tmp.path()));
  const auto names = Listing(tmp.path());
  ASSERT_EQ(names.size(), 2U);  // CURRENT and one snapshot directory
  EXPECT_EQ(names[0], "CURRENT");
  PlaceDb loaded;
  loaded.Load(tmp.path());
  EXPECT_EQ(loaded.Size(), 21);
}

TEST(PlaceDbSnapshotTest, SavingWhileAnotherThreadInsertsGivesConsistentSnapshots) {
  // Save writes the keyframes without holding the lock; each snapshot must
  // still be one consistent cut (Load cross-checks every graph slot against
  // its keyframe record and code).
  test::TempDir tmp;
  PlaceDb db(SmallCap(120));
  Fill(db, 20);
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (int i = 20; i < 400 && !done; ++i) {
      db.Insert(Keyframe("uav_a", i));
      db.Insert(Keyframe("uav_b", i));
    }
  });
  int saves = 0;
  for (int round = 0; round < 8; ++round) {
    const auto r = db.Save(tmp.path());
    ASSERT_TRUE(r.success) << r.reason;
    PlaceDb loaded(SmallCap(120));
    ASSERT_NO_THROW(loaded.Load(tmp.path()));
    EXPECT_EQ(loaded.Size(), r.keyframes);
    for (PlaceDb::Id id : loaded.Ids()) {
      const auto kf = loaded.Get(id);
      const auto q = loaded.Query(kf->global_descriptor, 1, kf->agent);
      ASSERT_EQ(q.matches.size(), 1U);
      EXPECT_EQ(q.matches[0].entry.id, id);
    }
    ++saves;
  }
  done = true;
  writer.join();
  EXPECT_EQ(saves, 8);
}

TEST(PlaceDbSnapshotTest, SaveIntoAnUnwritablePlaceFailsWithAReason) {
  PlaceDb db;
  Fill(db, 2);
  const auto r = db.Save("/proc/place_db_cannot_be_here");
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.reason.find("/proc/place_db_cannot_be_here"), std::string::npos) << r.reason;
}

// ------------------------------------------------------------ bad snapshots

class PlaceDbCorruptSnapshotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    PlaceDb source(SmallCap(80));
    Fill(source, 50);
    ASSERT_TRUE(source.Save(tmp_.path()).success);
    snap_ = CurrentSnapshot(tmp_.path());
    // The database that must survive failed loads untouched.
    Fill(db_, 7);
    before_ = Fingerprint(db_);
  }

  void ExpectUntouched() {
    EXPECT_EQ(db_.Size(), 14);
    EXPECT_EQ(Fingerprint(db_), before_);
    EXPECT_TRUE(db_.Insert(Keyframe("uav_a", 1000)).success);  // still usable
  }

  test::TempDir tmp_;
  std::string snap_;
  PlaceDb db_;
  std::vector<std::pair<PlaceDb::Id, float>> before_;
};

TEST_F(PlaceDbCorruptSnapshotTest, FlippedByteInTheKeyframesIsAChecksumError) {
  const std::string file = snap_ + "/keyframes.bin";
  FlipByte(file, fs::file_size(file) / 2);
  const InputError e = LoadError(db_, tmp_.path());
  EXPECT_EQ(e.kind(), InputErrorKind::kMalformedRow);
  EXPECT_EQ(e.file(), file);
  EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  ExpectUntouched();
}

TEST_F(PlaceDbCorruptSnapshotTest, TruncatedGraphIsReportedWithItsSize) {
  const std::string file = snap_ + "/graph_0.hnsw";
  fs::resize_file(file, fs::file_size(file) - 100);
  const InputError e = LoadError(db_, tmp_.path());
  EXPECT_EQ(e.kind(), InputErrorKind::kMalformedRow);
  EXPECT_EQ(e.file(), file);
  EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  ExpectUntouched();
}

TEST_F(PlaceDbCorruptSnapshotTest, TruncatedKeyframesAreReported) {
  const std::string file = snap_ + "/keyframes.bin";
  fs::resize_file(file, fs::file_size(file) / 3);
  const InputError e = LoadError(db_, tmp_.path());
  EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  ExpectUntouched();
}

TEST_F(PlaceDbCorruptSnapshotTest, CorruptGraphIsCaughtBeforeHnswlibReadsIt) {
  const std::string file = snap_ + "/graph_1.hnsw";
  FlipByte(file, 40);  // a header field: hnswlib alone would misallocate
  const InputError e = LoadError(db_, tmp_.path());
  EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
  ExpectUntouched();
}

TEST_F(PlaceDbCorruptSnapshotTest, CorruptOrTruncatedManifestIsReported) {
  const std::string file = snap_ + "/manifest.bin";
  FlipByte(file, 30);
  EXPECT_NE(std::string(LoadError(db_, tmp_.path()).what()).find("checksum"), std::string::npos);
  fs::resize_file(file, 20);
  EXPECT_NE(std::string(LoadError(db_, tmp_.path()).what()).find("truncated"), std::string::npos);
  ExpectUntouched();
}

TEST_F(PlaceDbCorruptSnapshotTest, NewerFormatVersionIsRefusedByName) {
  // Rewrite the version field and fix the manifest's own CRC, as a future
  // build would have written it.
  const std::string file = snap_ + "/manifest.bin";
  std::string bytes;
  {
    std::ifstream in(file, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  const uint32_t version = 2;
  std::memcpy(bytes.data() + 8, &version, sizeof(version));
  const uint32_t crc = internal::Crc32(bytes.data(), bytes.size() - 4);
  std::memcpy(bytes.data() + bytes.size() - 4, &crc, sizeof(crc));
  std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
  const InputError e = LoadError(db_, tmp_.path());
  EXPECT_EQ(e.kind(), InputErrorKind::kBadValue);
  EXPECT_NE(std::string(e.what()).find("version 2"), std::string::npos) << e.what();
  ExpectUntouched();
}

TEST_F(PlaceDbCorruptSnapshotTest, OtherDescriptorDimensionIsRefused) {
  PlaceDb::Options options;
  options.dim = 256;
  PlaceDb other(options);
  const InputError e = LoadError(other, tmp_.path());
  EXPECT_EQ(e.kind(), InputErrorKind::kBadValue);
  EXPECT_NE(std::string(e.what()).find("512-D"), std::string::npos) << e.what();
  EXPECT_EQ(other.Size(), 0);
}

TEST_F(PlaceDbCorruptSnapshotTest, MissingOrDanglingPointerIsReported) {
  std::ofstream(tmp_.path() + "/CURRENT", std::ios::trunc) << "snap-999\n";
  EXPECT_EQ(LoadError(db_, tmp_.path()).kind(), InputErrorKind::kMissingFile);
  std::ofstream(tmp_.path() + "/CURRENT", std::ios::trunc) << "../../etc\n";
  EXPECT_NE(std::string(LoadError(db_, tmp_.path()).what()).find("does not name a snapshot"),
            std::string::npos);
  fs::remove(tmp_.path() + "/CURRENT");
  EXPECT_EQ(LoadError(db_, tmp_.path()).kind(), InputErrorKind::kMissingFile);
  EXPECT_EQ(LoadError(db_, tmp_.path() + "/nowhere").kind(), InputErrorKind::kMissingFile);
  ExpectUntouched();
}

// -------------------------------------------------------------- crash safety

constexpr int kBatch = 10;  // keyframes inserted between two saves

/// The child: loads the snapshot, then grows it by kBatch keyframes per
/// save and reports every completed save on `report_fd`, until killed.
[[noreturn]] void SaveForever(const std::string& dir, int report_fd) {
  try {
    PlaceDb db;
    db.Load(dir);
    for (int round = 0; round < 200; ++round) {
      const int64_t next = db.Size();
      for (int i = 0; i < kBatch; ++i) {
        if (!db.Insert(Keyframe("uav_a", next + i)).success) _exit(3);
      }
      if (!db.Save(dir).success) _exit(4);
      const char done = 1;
      if (::write(report_fd, &done, 1) != 1) _exit(5);
    }
    _exit(0);
  } catch (...) {
    _exit(2);
  }
}

/// Waits (bounded) for `count` completed saves reported by the child.
int AwaitSaves(int fd, int count) {
  int seen = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (seen < count && std::chrono::steady_clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 1000) <= 0) continue;
    char buffer[64];
    const ssize_t n = ::read(fd, buffer, sizeof(buffer));
    if (n <= 0) break;  // the child exited
    seen += static_cast<int>(n);
  }
  return seen;
}

TEST(PlaceDbCrashTest, KilledWhileSavingAlwaysLeavesACompleteEarlierState) {
  test::TempDir tmp;
  {
    PlaceDb db;
    for (int i = 0; i < kBatch; ++i) ASSERT_TRUE(db.Insert(Keyframe("uav_a", i)).success);
    ASSERT_TRUE(db.Save(tmp.path()).success);
  }
  std::mt19937 rng(1234);
  int64_t size = kBatch;
  int64_t min_expected = kBatch;
  int mid_save_kills = 0;
  for (int iteration = 0; iteration < 12; ++iteration) {
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      ::close(fds[0]);
      SaveForever(tmp.path(), fds[1]);
    }
    ::close(fds[1]);
    // Let the child complete 0-2 saves, then kill it at a random moment of
    // what follows (loading, inserting, or any step of a save).
    const int wait_saves = std::uniform_int_distribution<int>(0, 2)(rng);
    const int seen = AwaitSaves(fds[0], wait_saves);
    ASSERT_EQ(seen, wait_saves) << "the saving child stopped early";
    std::this_thread::sleep_for(
        std::chrono::microseconds(std::uniform_int_distribution<int>(0, 40000)(rng)));
    ::kill(child, SIGKILL);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "child exited with " << WEXITSTATUS(status);
    const int more = AwaitSaves(fds[0], 1000);  // saves completed after the wait
    ::close(fds[0]);
    min_expected += static_cast<int64_t>(seen + more) * kBatch;

    bool partial = false;
    for (const auto& name : Listing(tmp.path())) {
      partial =
          partial || (name != "CURRENT" && tmp.path() + "/" + name != CurrentSnapshot(tmp.path()));
    }
    mid_save_kills += partial;

    // The state is one of the saved ones: whole batches, ids 0..n-1, every
    // keyframe bit-identical to what was inserted.
    PlaceDb db;
    ASSERT_NO_THROW(db.Load(tmp.path())) << "iteration " << iteration;
    const int64_t n = db.Size();
    EXPECT_EQ(n % kBatch, 0) << "a partial batch was loaded";
    EXPECT_GE(n, size) << "went back to an older state";
    EXPECT_GE(n, min_expected) << "a completed save was lost";
    const auto ids = db.Ids();
    ASSERT_EQ(static_cast<int64_t>(ids.size()), n);
    for (int64_t i = 0; i < n; ++i) {
      ASSERT_EQ(ids[static_cast<size_t>(i)], i);
      test::ExpectSameKeyframe(*db.Get(i), Keyframe("uav_a", i));
    }
    // And it answers queries from its graph: each keyframe finds itself.
    for (int64_t i = 0; i < n; i += 7) {
      const auto q = db.Query(db.Get(i)->global_descriptor, 1);
      ASSERT_EQ(q.matches.size(), 1U);
      EXPECT_EQ(q.matches[0].entry.id, i);
    }
    size = n;
    min_expected = n;
  }
  std::cout << "[ info ] 12 kills, " << mid_save_kills << " left a partial snapshot behind; final "
            << size << " keyframes\n";
  EXPECT_GT(size, kBatch);
}

}  // namespace
}  // namespace ag
