// HNSW retrieval against exact search (FAISS IndexFlatIP): recall@1 and
// recall@5 on trajectory-like descriptors (the realistic case), after
// eviction churn (refilled graph slots), and on uniform random vectors (the
// worst case, reported with a loose bound).

#include <faiss/IndexFlat.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <iostream>
#include <random>

#include "ground_server/place_db/place_db.h"
#include "ground_server/place_db/synthetic_places.h"
#include "tests/ground_server/place_db/place_db_test_util.h"

namespace ag {
namespace {

struct Recall {
  double at1 = 0;
  double at5 = 0;
};

/// Recall of db.Query against FAISS exact inner-product search over
/// `items` (id -> descriptor, the database's live content). A top-1 counts
/// as found when it is the exact top-1 or ties its similarity (1e-6).
Recall MeasureRecall(const PlaceDb& db, const std::map<PlaceDb::Id, std::vector<float>>& items,
                     const std::vector<std::vector<float>>& queries) {
  const int dim = static_cast<int>(items.begin()->second.size());
  faiss::IndexFlatIP exact(dim);
  std::vector<PlaceDb::Id> row_to_id;
  std::vector<float> data;
  for (const auto& [id, v] : items) {
    const std::vector<float> unit = test::Unit(v);
    data.insert(data.end(), unit.begin(), unit.end());
    row_to_id.push_back(id);
  }
  exact.add(static_cast<faiss::Index::idx_t>(row_to_id.size()), data.data());
  std::vector<float> query_data;
  for (const auto& q : queries) {
    const std::vector<float> unit = test::Unit(q);
    query_data.insert(query_data.end(), unit.begin(), unit.end());
  }
  const auto nq = static_cast<faiss::Index::idx_t>(queries.size());
  std::vector<float> similarity(static_cast<size_t>(nq) * 5);
  std::vector<faiss::Index::idx_t> rows(static_cast<size_t>(nq) * 5);
  exact.search(nq, query_data.data(), 5, similarity.data(), rows.data());

  Recall recall;
  for (size_t i = 0; i < queries.size(); ++i) {
    const auto r = db.Query(queries[i], 5);
    EXPECT_TRUE(r.success) << r.reason;
    if (r.matches.size() != 5) {
      ADD_FAILURE() << "query " << i << " returned " << r.matches.size() << " matches";
      continue;
    }
    const PlaceDb::Id exact_top = row_to_id[static_cast<size_t>(rows[i * 5])];
    recall.at1 += r.matches[0].entry.id == exact_top ||
                  std::abs(r.matches[0].similarity - similarity[i * 5]) <= 1e-6F;
    int common = 0;
    for (const auto& m : r.matches) {
      for (int j = 0; j < 5; ++j)
        common += m.entry.id == row_to_id[static_cast<size_t>(rows[i * 5 + j])];
    }
    recall.at5 += common / 5.0;
  }
  recall.at1 /= static_cast<double>(queries.size());
  recall.at5 /= static_cast<double>(queries.size());
  return recall;
}

/// Queries as a UGV would pose them: near a UAV keyframe's place (a few
/// metres and tenths of a radian off), with stronger appearance noise.
std::vector<std::vector<float>> PlaceQueries(const SyntheticPlaces& places,
                                             const std::vector<Pose>& flight, int count,
                                             uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<size_t> pick(0, flight.size() - 1);
  std::normal_distribution<double> offset_m(0.0, 3.0);
  std::normal_distribution<double> offset_rad(0.0, 0.3);
  std::vector<std::vector<float>> queries;
  for (int i = 0; i < count; ++i) {
    Pose T = flight[pick(rng)];
    T.translation() += Eigen::Vector3d(offset_m(rng), offset_m(rng), 0);
    T.linear() = RotZ(offset_rad(rng)) * T.linear();
    queries.push_back(places.Descriptor(T, 0.5, rng));
  }
  return queries;
}

TEST(PlaceDbRecallTest, TrajectoryDescriptorsAtDefaultOptions) {
  // 10k keyframes: the size of the retrieval target (< 0.1 ms, see
  // tools/bench/place_db_bench) and half the default cap.
  const SyntheticPlaces places({});
  const auto flight = SyntheticFlight(10000, 2.0, 500.0, 11);
  PlaceDb db;
  std::map<PlaceDb::Id, std::vector<float>> items;
  for (int i = 0; i < 10000; ++i) {
    const AirKeyframe kf = test::FlightKeyframe(places, flight, "uav1", i, 0);
    const auto r = db.Insert(kf);
    ASSERT_TRUE(r.success) << r.reason;
    items[r.id] = kf.global_descriptor;
  }
  const Recall recall = MeasureRecall(db, items, PlaceQueries(places, flight, 1000, 1));
  std::cout << "[ info ] trajectory 10000: recall@1 " << recall.at1 << ", recall@5 " << recall.at5
            << " (ef_search " << db.GetOptions().ef_search << ")\n";
  EXPECT_GE(recall.at1, 0.99);
  EXPECT_GE(recall.at5, 0.98);
}

TEST(PlaceDbRecallTest, TrajectoryDescriptorsAfterEvictionChurn) {
  // 5000 inserted under a cap of 1500: 3500 evictions, so almost every
  // graph slot has been refilled with another keyframe (hnswlib updatePoint).
  const SyntheticPlaces places({});
  const auto flight = SyntheticFlight(5000, 2.0, 500.0, 12);
  PlaceDb::Options options;
  options.max_keyframes = 1500;
  options.eviction = "oldest";
  PlaceDb db(options);
  std::map<PlaceDb::Id, std::vector<float>> items;
  for (int i = 0; i < 5000; ++i) {
    const AirKeyframe kf = test::FlightKeyframe(places, flight, "uav1", i, 0);
    const auto r = db.Insert(kf);
    ASSERT_TRUE(r.success) << r.reason;
    items[r.id] = kf.global_descriptor;
    for (PlaceDb::Id id : r.evicted) items.erase(id);
  }
  ASSERT_EQ(items.size(), 1500U);
  EXPECT_LE(db.GetStats().graph_slots, 1501);
  const std::vector<Pose> recent(flight.end() - 1500, flight.end());
  const Recall recall = MeasureRecall(db, items, PlaceQueries(places, recent, 500, 2));
  std::cout << "[ info ] trajectory churn 1500/5000: recall@1 " << recall.at1 << ", recall@5 "
            << recall.at5 << "\n";
  EXPECT_GE(recall.at1, 0.99);
  EXPECT_GE(recall.at5, 0.97);
}

TEST(PlaceDbRecallTest, UniformRandomVectorsWorstCase) {
  std::mt19937 rng(3);
  PlaceDb db;
  std::map<PlaceDb::Id, std::vector<float>> items;
  for (int i = 0; i < 5000; ++i) {
    std::vector<float> v = RandomUnitVector(512, rng);
    const auto r = db.Insert(SyntheticKeyframe("uav1", i, Pose::Identity(), v, 0, 0, rng));
    ASSERT_TRUE(r.success) << r.reason;
    items[r.id] = std::move(v);
  }
  std::vector<std::vector<float>> queries(500);
  for (auto& q : queries) q = RandomUnitVector(512, rng);
  const Recall at_default = MeasureRecall(db, items, queries);
  db.SetEfSearch(512);
  const Recall at_512 = MeasureRecall(db, items, queries);
  std::cout << "[ info ] uniform random 5000: recall@1 " << at_default.at1 << ", recall@5 "
            << at_default.at5 << " at the default ef; " << at_512.at1 << ", " << at_512.at5
            << " at ef 512\n";
  // No neighbourhood structure at all, so the default ef finds the exact
  // neighbour only sometimes; a random answer would score 0.0002. A larger
  // candidate list must converge to the exact answer on the same graph.
  EXPECT_GE(at_default.at1, 0.2);
  EXPECT_GE(at_512.at1, 0.95);
  EXPECT_GE(at_512.at5, 0.95);
}

}  // namespace
}  // namespace ag
