#include "ground_server/matching/descriptor_matcher.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <random>

namespace ag {
namespace {

cv::Mat RandomUnitRows(int rows, int cols, std::mt19937& rng) {
  std::normal_distribution<float> n(0, 1);
  cv::Mat m(rows, cols, CV_32F);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) m.at<float>(i, j) = n(rng);
    {
      cv::Mat r = m.row(i);
      cv::normalize(r, r);
    }
  }
  return m;
}

// b = a permuted, with noise, plus distractors.
struct Pair {
  cv::Mat a, b;
  std::vector<int> truth;  // truth[i] = row of b matching a's row i
};

Pair MakePair(int n, int distractors, float noise, uint32_t seed) {
  std::mt19937 rng(seed);
  Pair p;
  p.a = RandomUnitRows(n, 64, rng);
  std::vector<int> perm(n + distractors);
  for (size_t i = 0; i < perm.size(); ++i) perm[i] = static_cast<int>(i);
  std::shuffle(perm.begin(), perm.end(), rng);
  p.b = RandomUnitRows(n + distractors, 64, rng);
  std::normal_distribution<float> nd(0, noise);
  p.truth.resize(n);
  for (int i = 0; i < n; ++i) {
    cv::Mat row = p.a.row(i).clone();
    for (int j = 0; j < 64; ++j) row.at<float>(0, j) += nd(rng);
    cv::normalize(row, row);
    row.copyTo(p.b.row(perm[i]));
    p.truth[i] = perm[i];
  }
  return p;
}

class MatcherTest : public ::testing::TestWithParam<std::string> {};

TEST_P(MatcherTest, FindsTrueMatchesAndRejectsAmbiguous) {
  const Pair p = MakePair(500, 300, 0.03f, 1);
  MatcherOptions o;
  o.backend = GetParam();
  const auto matches = MatchDescriptors(p.a, p.b, o);
  int correct = 0;
  for (const auto& m : matches) correct += p.truth[m.a] == m.b;
  EXPECT_GT(matches.size(), 450u);
  EXPECT_EQ(correct, static_cast<int>(matches.size()));
  // Ratio test: a duplicated row of b makes its match ambiguous.
  cv::Mat b2;
  cv::vconcat(p.b, p.b.row(p.truth[0]), b2);
  const auto m2 = MatchDescriptors(p.a, b2, o);
  for (const auto& m : m2) EXPECT_NE(m.a, 0);
}

TEST_P(MatcherTest, MutualCheckDropsOneSidedMatches) {
  // Two rows of a share the same nearest row of b: at most one survives.
  std::mt19937 rng(2);
  cv::Mat b = RandomUnitRows(50, 64, rng);
  cv::Mat a;
  cv::vconcat(b.row(3), b.row(3) * 0.99 + b.row(4) * 0.01, a);
  {
    cv::Mat r = a.row(1);
    cv::normalize(r, r);
  }
  MatcherOptions o;
  o.backend = GetParam();
  o.ratio = 1.0;
  const auto matches = MatchDescriptors(a, b, o);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].a, 0);
  EXPECT_EQ(matches[0].b, 3);
  o.mutual = false;
  EXPECT_EQ(MatchDescriptors(a, b, o).size(), 2u);
}

INSTANTIATE_TEST_SUITE_P(Backends, MatcherTest, ::testing::Values("gemm", "faiss", "opencv"));

void ExpectBackendsAgree(const Pair& p, size_t min_matches) {
  MatcherOptions f;
  f.backend = "faiss";
  const auto mf = MatchDescriptors(p.a, p.b, f);
  ASSERT_GT(mf.size(), min_matches);
  for (const char* other : {"opencv", "gemm"}) {
    SCOPED_TRACE(other);
    MatcherOptions c;
    c.backend = other;
    const auto mc = MatchDescriptors(p.a, p.b, c);
    ASSERT_EQ(mf.size(), mc.size());
    for (size_t i = 0; i < mf.size(); ++i) {
      EXPECT_EQ(mf[i].a, mc[i].a);
      EXPECT_EQ(mf[i].b, mc[i].b);
      EXPECT_NEAR(mf[i].distance, mc[i].distance, 1e-3);
    }
  }
}

TEST(MatcherTest, BackendsAgree) { ExpectBackendsAgree(MakePair(1024, 0, 0.2f, 3), 500); }

TEST(MatcherTest, BackendsAgreeForAFewRowsAgainstMany) {
  // Stage 1's tracks: under 100 rows against a whole keyframe, which the
  // gemm backend multiplies the other way round.
  ExpectBackendsAgree(MakePair(60, 940, 0.2f, 8), 30);
  // The ratio and mutual tests still see b's rows: the nearest neighbours
  // of a few rows.
  ExpectBackendsAgree(MakePair(3, 500, 0.05f, 9), 2);
}

TEST(MatcherTest, DimensionMismatchIsAnError) {
  std::mt19937 rng(4);
  EXPECT_THROW(MatchDescriptors(RandomUnitRows(3, 64, rng), RandomUnitRows(3, 128, rng), {}),
               std::invalid_argument);
  EXPECT_TRUE(MatchDescriptors(cv::Mat(), RandomUnitRows(3, 64, rng), {}).empty());
}

}  // namespace
}  // namespace ag
