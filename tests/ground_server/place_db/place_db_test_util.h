#pragma once

// Helpers shared by the place database tests.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "ground_server/place_db/place_db.h"
#include "ground_server/place_db/synthetic_places.h"

namespace ag::test {

/// Deterministic keyframe number `seq` of a synthetic flight: the same
/// (agent, seq, flight seed) always gives bit-identical content.
inline AirKeyframe FlightKeyframe(const SyntheticPlaces& places, const std::vector<Pose>& flight,
                                  const std::string& agent, int64_t seq, int keypoints = 16,
                                  int local_dim = 32) {
  std::mt19937 rng(static_cast<uint32_t>(seq * 7919 + agent.size()));
  const Pose& T = flight.at(static_cast<size_t>(seq));
  return SyntheticKeyframe(agent, seq, T, places.Descriptor(T, 0.3, rng), keypoints, local_dim,
                           rng);
}

inline float Dot(const std::vector<float>& a, const std::vector<float>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += double{a[i]} * b[i];
  return static_cast<float>(s);
}

inline std::vector<float> Unit(std::vector<float> v) {
  const double n = std::sqrt(double{Dot(v, v)});
  for (float& x : v) x = static_cast<float>(x / n);
  return v;
}

/// Exact top-k ids by cosine similarity (ties: lower id first).
inline std::vector<PlaceDb::Id> ExactTopK(const std::map<PlaceDb::Id, std::vector<float>>& items,
                                          const std::vector<float>& query, int k) {
  const std::vector<float> q = Unit(query);
  std::vector<std::pair<float, PlaceDb::Id>> scored;
  scored.reserve(items.size());
  for (const auto& [id, v] : items) scored.emplace_back(Dot(q, Unit(v)), id);
  std::sort(scored.begin(), scored.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  std::vector<PlaceDb::Id> ids;
  for (size_t i = 0; i < scored.size() && i < static_cast<size_t>(k); ++i) {
    ids.push_back(scored[i].second);
  }
  return ids;
}

/// Field-by-field equality of two keyframes, bit-exact for all numbers.
inline void ExpectSameKeyframe(const AirKeyframe& a, const AirKeyframe& b) {
  EXPECT_EQ(a.agent, b.agent);
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.camera_id, b.camera_id);
  EXPECT_TRUE(a.T_wa_c.matrix() == b.T_wa_c.matrix()) << a.seq;
  EXPECT_EQ(a.global_descriptor, b.global_descriptor);
  EXPECT_EQ(a.features.keypoints, b.features.keypoints);
  EXPECT_EQ(a.features.scores, b.features.scores);
  EXPECT_EQ(a.features.descriptor_type, b.features.descriptor_type);
  const cv::Mat& da = a.features.descriptors;
  const cv::Mat& db = b.features.descriptors;
  ASSERT_EQ(da.rows, db.rows);
  ASSERT_EQ(da.cols, db.cols);
  ASSERT_EQ(da.type(), db.type());
  for (int r = 0; r < da.rows; ++r) {
    EXPECT_EQ(std::memcmp(da.ptr(r), db.ptr(r), da.cols * da.elemSize()), 0) << "row " << r;
  }
}

}  // namespace ag::test
