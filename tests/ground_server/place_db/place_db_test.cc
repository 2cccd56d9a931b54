#include "ground_server/place_db/place_db.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <thread>

#include "common/config/options.h"
#include "ground_server/place_db/binary_io.h"
#include "ground_server/place_db/place_db_state.h"
#include "ground_server/place_db/synthetic_places.h"
#include "tests/ground_server/place_db/place_db_test_util.h"

namespace ag {
namespace {

using test::Dot;
using test::ExactTopK;
using test::Unit;

AirKeyframe RandomKeyframe(const std::string& agent, int64_t seq, std::mt19937& rng,
                           int keypoints = 8, int dim = 512) {
  Pose T = Pose::Identity();
  T.translation() = Eigen::Vector3d(static_cast<double>(seq), 0, 30);
  return SyntheticKeyframe(agent, seq, T, RandomUnitVector(dim, rng), keypoints, 32, rng);
}

// ------------------------------------------------------------------ options

TEST(PlaceDbOptionsTest, DefaultsAreValidAndBadValuesNameTheField) {
  EXPECT_NO_THROW(CheckOptions(PlaceDb::Options()));
  auto error_of = [](const std::string& yaml) -> std::string {
    try {
      LoadOptions<PlaceDb::Options>(YAML::Load(yaml), "place_db.yaml");
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error_of("hnsw_m: 1").find("hnsw_m"), std::string::npos);
  EXPECT_NE(error_of("eviction: lru").find("eviction"), std::string::npos);
  EXPECT_NE(error_of("max_keyframes: 0").find("max_keyframes"), std::string::npos);
  EXPECT_NE(error_of("ef_serch: 10").find("unknown key"), std::string::npos);
  const auto o = LoadOptions<PlaceDb::Options>(YAML::Load("ef_search: 32\neviction: oldest"), "f");
  EXPECT_EQ(o.ef_search, 32);
  EXPECT_EQ(o.eviction, "oldest");
  PlaceDb::Options bad;
  bad.dim = 0;
  EXPECT_THROW(PlaceDb db(bad), OptionError);
}

TEST(PlaceDbBinaryIoTest, Crc32MatchesTheStandardCheckValue) {
  EXPECT_EQ(internal::Crc32("123456789", 9), 0xCBF43926U);
  // Running checksum over pieces equals the one-shot checksum.
  EXPECT_EQ(internal::Crc32("6789", 4, internal::Crc32("12345", 5)), 0xCBF43926U);
}

// ------------------------------------------------------- insert, query, get

TEST(PlaceDbTest, InsertedKeyframesAreRetrievedWithTheirMetadata) {
  PlaceDb db;
  std::mt19937 rng(1);
  std::vector<AirKeyframe> kfs(3);
  for (int i = 0; i < 3; ++i) kfs[i] = RandomKeyframe("uav1", 10 + i, rng, 50);
  std::vector<PlaceDb::Id> ids;
  for (const AirKeyframe& kf : kfs) {
    const auto r = db.Insert(kf);
    ASSERT_TRUE(r.success) << r.reason;
    EXPECT_TRUE(r.evicted.empty());
    ids.push_back(r.id);
  }
  EXPECT_EQ(ids, (std::vector<PlaceDb::Id>{0, 1, 2}));
  EXPECT_EQ(db.Size(), 3);
  for (int i = 0; i < 3; ++i) {
    const auto q = db.Query(kfs[i].global_descriptor, 2);
    ASSERT_TRUE(q.success) << q.reason;
    ASSERT_EQ(q.matches.size(), 2U);
    const PlaceDb::Match& m = q.matches[0];
    EXPECT_EQ(m.entry.id, ids[i]);
    EXPECT_NEAR(m.similarity, 1.0F, 1e-5F);
    EXPECT_LT(q.matches[1].similarity, 0.5F);
    EXPECT_EQ(m.entry.agent, "uav1");
    EXPECT_EQ(m.entry.seq, 10 + i);
    EXPECT_EQ(m.entry.t_ns, kfs[i].t_ns);
    EXPECT_TRUE(m.entry.T_wa_c.isApprox(kfs[i].T_wa_c));
    ASSERT_NE(m.entry.keyframe, nullptr);
    test::ExpectSameKeyframe(*m.entry.keyframe, kfs[i]);
    const auto kf = db.Get(ids[i]);
    ASSERT_NE(kf, nullptr);
    EXPECT_EQ(kf.get(), m.entry.keyframe.get());
    ASSERT_TRUE(db.GetEntry(ids[i]).has_value());
    EXPECT_EQ(db.GetEntry(ids[i])->seq, 10 + i);
  }
  EXPECT_EQ(db.Get(99), nullptr);
  EXPECT_FALSE(db.GetEntry(99).has_value());
}

TEST(PlaceDbTest, StoredKeyframeDoesNotShareBuffersWithTheCaller) {
  PlaceDb db;
  std::mt19937 rng(2);
  AirKeyframe kf = RandomKeyframe("uav1", 0, rng, 20);
  std::mt19937 same_rng(2);
  const AirKeyframe original = RandomKeyframe("uav1", 0, same_rng, 20);
  const auto r = db.Insert(kf);  // a shallow cv::Mat copy of kf's descriptors
  ASSERT_TRUE(r.success);
  kf.features.descriptors.setTo(0.0F);  // the caller reuses its buffer
  test::ExpectSameKeyframe(*db.Get(r.id), original);
}

TEST(PlaceDbTest, DescriptorsAreNormalisedSoSimilarityIsCosine) {
  PlaceDb db;
  std::mt19937 rng(3);
  AirKeyframe kf = RandomKeyframe("uav1", 0, rng);
  const std::vector<float> unit = kf.global_descriptor;
  for (float& x : kf.global_descriptor) x *= 3.0F;
  ASSERT_TRUE(db.Insert(kf).success);
  std::vector<float> query = unit;
  for (float& x : query) x *= 0.25F;
  const auto q = db.Query(query, 1);
  ASSERT_EQ(q.matches.size(), 1U);
  EXPECT_NEAR(q.matches[0].similarity, 1.0F, 1e-5F);
  // The keyframe is kept as received.
  EXPECT_EQ(q.matches[0].entry.keyframe->global_descriptor, kf.global_descriptor);
}

TEST(PlaceDbTest, BadInputIsRejectedWithAReasonAndLosesNothing) {
  PlaceDb db;
  std::mt19937 rng(4);
  const AirKeyframe good = RandomKeyframe("uav1", 0, rng);
  ASSERT_TRUE(db.Insert(good).success);

  auto expect_rejected = [&](AirKeyframe kf, PlaceDb::InsertStatus status,
                             const std::vector<std::string>& words) {
    const auto r = db.Insert(std::move(kf));
    EXPECT_FALSE(r.success);
    EXPECT_EQ(r.status, status);
    EXPECT_EQ(r.id, -1);
    for (const std::string& w : words) {
      EXPECT_NE(r.reason.find(w), std::string::npos) << "'" << w << "' not in: " << r.reason;
    }
    EXPECT_EQ(db.Size(), 1);
    const auto q = db.Query(good.global_descriptor, 1);
    ASSERT_EQ(q.matches.size(), 1U);
    EXPECT_EQ(q.matches[0].entry.id, 0);
  };

  AirKeyframe kf = RandomKeyframe("uav1", 1, rng);
  kf.global_descriptor.pop_back();
  expect_rejected(kf, PlaceDb::InsertStatus::kBadDescriptor, {"511 values", "expected 512"});
  kf = RandomKeyframe("uav1", 1, rng);
  kf.global_descriptor[7] = std::numeric_limits<float>::quiet_NaN();
  expect_rejected(kf, PlaceDb::InsertStatus::kBadDescriptor, {"value 7", "not finite"});
  kf.global_descriptor[7] = std::numeric_limits<float>::infinity();
  expect_rejected(kf, PlaceDb::InsertStatus::kBadDescriptor, {"not finite", "inf"});
  kf.global_descriptor.assign(512, 0.0F);
  expect_rejected(kf, PlaceDb::InsertStatus::kBadDescriptor, {"zero norm"});
  kf = RandomKeyframe("UAV-1", 1, rng);
  expect_rejected(kf, PlaceDb::InsertStatus::kBadKeyframe, {"agent name", "UAV-1"});
  kf = RandomKeyframe("uav1", 1, rng);
  kf.T_wa_c.translation().x() = std::numeric_limits<double>::quiet_NaN();
  expect_rejected(kf, PlaceDb::InsertStatus::kBadKeyframe, {"T_wa_c"});
  kf = RandomKeyframe("uav1", 1, rng);
  kf.features.keypoints.pop_back();
  expect_rejected(kf, PlaceDb::InsertStatus::kBadKeyframe, {"8 keypoint scores for 7 keypoints"});
  kf.features.scores.pop_back();
  expect_rejected(kf, PlaceDb::InsertStatus::kBadKeyframe, {"8 rows for 7 keypoints"});
  kf = RandomKeyframe("uav1", 0, rng);
  expect_rejected(kf, PlaceDb::InsertStatus::kDuplicate, {"seq 0", "id 0"});

  EXPECT_FALSE(db.Query(std::vector<float>(256, 1.0F), 1).success);
  const auto wrong = db.Query(std::vector<float>(256, 1.0F), 1);
  EXPECT_NE(wrong.reason.find("256 values"), std::string::npos) << wrong.reason;
  std::vector<float> nan_query = good.global_descriptor;
  nan_query[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(db.Query(nan_query, 1).success);
  EXPECT_FALSE(db.Query(good.global_descriptor, 0).success);
}

TEST(PlaceDbTest, GraphGrowsBeyondItsInitialCapacityWithoutLosingEntries) {
  PlaceDb::Options options;
  options.initial_capacity = 4;
  PlaceDb db(options);
  std::mt19937 rng(5);
  std::vector<AirKeyframe> kfs;
  for (int i = 0; i < 300; ++i) {
    kfs.push_back(RandomKeyframe("uav1", i, rng, 0));
    ASSERT_TRUE(db.Insert(kfs.back()).success);
  }
  EXPECT_EQ(db.GetStats().graph_slots, 300);
  int found = 0;
  for (int i = 0; i < 300; ++i) {
    const auto q = db.Query(kfs[i].global_descriptor, 1);
    found += q.matches.size() == 1 && q.matches[0].entry.id == i;
  }
  EXPECT_EQ(found, 300);
}

// --------------------------------------------------------------- agent filter

TEST(PlaceDbTest, AgentFilterReturnsOnlyThatAgentAndMatchesExactSearch) {
  PlaceDb db;
  const SyntheticPlaces places({});
  std::map<std::string, std::map<PlaceDb::Id, std::vector<float>>> by_agent;
  std::map<PlaceDb::Id, std::vector<float>> all;
  const std::vector<std::string> agents = {"uav_a", "uav_b", "uav_c"};
  for (size_t a = 0; a < agents.size(); ++a) {
    // All three fly over the same 300 m square: cross-agent neighbours exist.
    const auto flight = SyntheticFlight(200, 2.0, 300.0, static_cast<uint32_t>(10 + a));
    for (int i = 0; i < 200; ++i) {
      const AirKeyframe kf = test::FlightKeyframe(places, flight, agents[a], i, 0);
      const auto r = db.Insert(kf);
      ASSERT_TRUE(r.success) << r.reason;
      by_agent[agents[a]][r.id] = kf.global_descriptor;
      all[r.id] = kf.global_descriptor;
    }
  }
  const auto queries = SyntheticFlight(60, 3.0, 300.0, 99);
  std::mt19937 rng(6);
  int top1_filtered = 0;
  int top1_all = 0;
  for (const Pose& T : queries) {
    const std::vector<float> q = places.Descriptor(T, 0.5, rng);
    const auto r = db.Query(q, 5, std::string("uav_b"));
    ASSERT_TRUE(r.success);
    ASSERT_EQ(r.matches.size(), 5U);
    for (const auto& m : r.matches) EXPECT_EQ(m.entry.agent, "uav_b");
    for (size_t i = 1; i < r.matches.size(); ++i) {
      EXPECT_GE(r.matches[i - 1].similarity, r.matches[i].similarity);
    }
    top1_filtered += r.matches[0].entry.id == ExactTopK(by_agent["uav_b"], q, 1)[0];
    const auto u = db.Query(q, 5);
    ASSERT_EQ(u.matches.size(), 5U);
    top1_all += u.matches[0].entry.id == ExactTopK(all, q, 1)[0];
  }
  // 200 entries per graph at ef_search 64: the search is practically exact.
  EXPECT_GE(top1_filtered, 59);
  EXPECT_GE(top1_all, 59);
  const auto unknown = db.Query(places.Descriptor(queries[0], 0.0, rng), 3, std::string("uav_z"));
  EXPECT_TRUE(unknown.success);
  EXPECT_TRUE(unknown.matches.empty());
  EXPECT_EQ(db.Ids(std::string("uav_c")).size(), 200U);
}

// ------------------------------------------------------------------- eviction

TEST(PlaceDbEvictionTest, OldestPolicyDropsTheOldestAndReusesGraphSlots) {
  PlaceDb::Options options;
  options.max_keyframes = 10;
  options.eviction = "oldest";
  PlaceDb db(options);
  std::mt19937 rng(7);
  std::vector<AirKeyframe> kfs;
  for (int i = 0; i < 25; ++i) {
    kfs.push_back(RandomKeyframe("uav1", i, rng, 0));
    const auto r = db.Insert(kfs.back());
    ASSERT_TRUE(r.success);
    if (i < 10) {
      EXPECT_TRUE(r.evicted.empty());
    } else {
      EXPECT_EQ(r.evicted, (std::vector<PlaceDb::Id>{i - 10}));
    }
    EXPECT_LE(db.Size(), 10);
  }
  std::vector<PlaceDb::Id> expected;
  for (int i = 15; i < 25; ++i) expected.push_back(i);
  EXPECT_EQ(db.Ids(), expected);
  EXPECT_EQ(db.Get(0), nullptr);
  const auto stats = db.GetStats();
  EXPECT_EQ(stats.keyframes, 10);
  EXPECT_EQ(stats.graph_slots, 11);  // one slot stays free between insert and evict
  EXPECT_EQ(stats.deleted_slots, 1);
  // Evicted keyframes are never returned, even when asked for everything.
  for (int i = 0; i < 25; ++i) {
    const auto q = db.Query(kfs[i].global_descriptor, 25);
    ASSERT_EQ(q.matches.size(), 10U);
    for (const auto& m : q.matches) EXPECT_GE(m.entry.id, 15);
    if (i >= 15) {
      EXPECT_EQ(q.matches[0].entry.id, i);
    }
  }
}

/// Reference for "thin": the interior keyframe with the smallest gap to its
/// nearer neighbour, recomputed from scratch (ties: lower id).
PlaceDb::Id ReferenceThinVictim(const std::map<int64_t, std::pair<PlaceDb::Id, Pose>>& live,
                                double w) {
  if (live.size() < 3) return live.begin()->second.first;
  double best = std::numeric_limits<double>::infinity();
  PlaceDb::Id best_id = -1;
  for (auto it = std::next(live.begin()); std::next(it) != live.end(); ++it) {
    const double cost =
        std::min(internal::ThinGap(it->second.second, std::prev(it)->second.second, w),
                 internal::ThinGap(it->second.second, std::next(it)->second.second, w));
    if (cost < best || (cost == best && it->second.first < best_id)) {
      best = cost;
      best_id = it->second.first;
    }
  }
  return best_id;
}

TEST(PlaceDbEvictionTest, ThinPolicyMatchesABruteForceReference) {
  PlaceDb::Options options;
  options.max_keyframes = 30;
  options.eviction = "thin";
  PlaceDb db(options);
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> step(0.0, 3.0);
  std::uniform_real_distribution<double> turn(-0.3, 0.3);
  std::map<int64_t, std::pair<PlaceDb::Id, Pose>> live;
  Pose T = Pose::Identity();
  int evictions = 0;
  for (int i = 0; i < 150; ++i) {
    // Irregular flight: hovering stretches (step 0) between normal ones.
    const double s = (i / 10) % 3 == 0 ? 0.0 : step(rng);
    T.translation() += Eigen::Vector3d(s, 0.3 * s, 0);
    T.linear() = RotZ(turn(rng)) * T.linear();
    AirKeyframe kf = RandomKeyframe("uav1", i, rng, 0);
    kf.T_wa_c = T;
    const auto r = db.Insert(kf);
    ASSERT_TRUE(r.success);
    live[i] = {r.id, T};
    if (live.size() > 30) {
      const PlaceDb::Id expected =
          ReferenceThinVictim(live, options.thin_rotation_weight_m_per_rad);
      ASSERT_EQ(r.evicted, (std::vector<PlaceDb::Id>{expected})) << "insert " << i;
      for (auto it = live.begin(); it != live.end(); ++it) {
        if (it->second.first == expected) {
          live.erase(it);
          break;
        }
      }
      ++evictions;
    }
  }
  EXPECT_EQ(evictions, 120);
  // The first keyframe (an endpoint) is never thinned away.
  EXPECT_NE(db.Get(0), nullptr);
}

TEST(PlaceDbEvictionTest, CapsTakeFromTheAgentWithTheMostKeyframes) {
  PlaceDb::Options options;
  options.max_keyframes = 20;
  PlaceDb db(options);
  std::mt19937 rng(9);
  for (int i = 0; i < 15; ++i) ASSERT_TRUE(db.Insert(RandomKeyframe("uav_a", i, rng, 0)).success);
  for (int i = 0; i < 10; ++i) {
    const auto r = db.Insert(RandomKeyframe("uav_b", i, rng, 0));
    ASSERT_TRUE(r.success);
    for (PlaceDb::Id id : r.evicted) EXPECT_EQ(db.GetEntry(id), std::nullopt);
    for (PlaceDb::Id id : r.evicted) EXPECT_LT(id, 15) << "evicted from uav_b";
  }
  EXPECT_EQ(db.Ids(std::string("uav_a")).size(), 10U);
  EXPECT_EQ(db.Ids(std::string("uav_b")).size(), 10U);
}

TEST(PlaceDbEvictionTest, ByteCapBoundsMemoryAndOversizedKeyframesAreRejected) {
  std::mt19937 rng(10);
  const int64_t one = KeyframeBytes(RandomKeyframe("uav1", 0, rng, 100));
  PlaceDb::Options options;
  options.max_bytes = 5 * one + one / 2;
  PlaceDb db(options);
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(db.Insert(RandomKeyframe("uav1", i, rng, 100)).success);
    EXPECT_LE(db.GetStats().keyframe_bytes, options.max_bytes);
  }
  EXPECT_EQ(db.Size(), 5);
  const auto big = db.Insert(RandomKeyframe("uav1", 100, rng, 1000));
  EXPECT_FALSE(big.success);
  EXPECT_EQ(big.status, PlaceDb::InsertStatus::kTooLarge);
  EXPECT_NE(big.reason.find("max_bytes"), std::string::npos);
  EXPECT_EQ(db.Size(), 5);
  EXPECT_EQ(db.GetStats().keyframe_bytes, 5 * one);
}

// ---------------------------------------------------------------- concurrency

TEST(PlaceDbTest, ConcurrentReadersSeeConsistentResultsWhileOneThreadWrites) {
  PlaceDb::Options options;
  options.max_keyframes = 300;
  options.initial_capacity = 16;  // several resizes while readers run
  PlaceDb db(options);
  const SyntheticPlaces places({});
  const auto flight = SyntheticFlight(1500, 2.0, 400.0, 3);
  std::atomic<bool> done{false};
  std::atomic<int> failures{0};
  std::atomic<int> queries{0};
  auto reader = [&](uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<size_t> pick(0, flight.size() - 1);
    while (!done.load()) {
      const std::vector<float> q = places.Descriptor(flight[pick(rng)], 0.5, rng);
      const auto r = db.Query(q, 5, std::string("uav1"));
      if (!r.success) ++failures;
      for (const auto& m : r.matches) {
        // The keyframe handed out is whole and its similarity is its own.
        if (m.entry.keyframe == nullptr || m.entry.keyframe->agent != "uav1" ||
            std::abs(Dot(Unit(m.entry.keyframe->global_descriptor), Unit(q)) - m.similarity) >
                1e-4F) {
          ++failures;
        }
      }
      ++queries;
    }
  };
  std::thread r1(reader, 1);
  std::thread r2(reader, 2);
  for (int i = 0; i < 1500; ++i) {
    const auto r = db.Insert(test::FlightKeyframe(places, flight, "uav1", i, 4));
    if (!r.success) ++failures;
  }
  done = true;
  r1.join();
  r2.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_GT(queries.load(), 0);
  EXPECT_EQ(db.Size(), 300);
}

}  // namespace
}  // namespace ag
