#include "ground_server/matching/descriptor_matcher.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
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

// The plain scan the gemm backend's vectorised one must equal: nearest
// (first index on ties) and second nearest by squared distance, both ways.
std::vector<DescriptorMatch> PlainScan(const cv::Mat& a, const cv::Mat& b, float ratio) {
  std::vector<int> nearest_a(b.rows, -1);
  std::vector<float> best_b(b.rows, INFINITY);
  std::vector<std::array<float, 2>> d12(a.rows, {INFINITY, INFINITY});
  std::vector<int> nearest_b(a.rows, -1);
  for (int i = 0; i < a.rows; ++i) {
    for (int j = 0; j < b.rows; ++j) {
      const float d = static_cast<float>(cv::norm(a.row(i), b.row(j), cv::NORM_L2SQR));
      if (d < d12[i][0]) {
        d12[i] = {d, d12[i][0]};
        nearest_b[i] = j;
      } else if (d < d12[i][1]) {
        d12[i][1] = d;
      }
      if (d < best_b[j]) {
        best_b[j] = d;
        nearest_a[j] = i;
      }
    }
  }
  std::vector<DescriptorMatch> out;
  for (int i = 0; i < a.rows; ++i) {
    const int j = nearest_b[i];
    if (j >= 0 && d12[i][0] <= ratio * ratio * d12[i][1] && nearest_a[j] == i) {
      out.push_back({i, j, std::sqrt(d12[i][0])});
    }
  }
  return out;
}

TEST(MatcherTest, GemmEqualsThePlainScanAroundItsLaneWidth) {
  // The gemm backend scans each row's distances in 16 lanes and pads the
  // last; sizes below, at and above multiples of 16, with duplicated rows
  // in b (a tie for the nearest must fail the ratio test, and the first of
  // tied rows of a must win a column).
  std::mt19937 rng(5);
  for (int nb : {1, 2, 15, 16, 17, 31, 32, 33, 100}) {
    for (int na : {1, 16, 17, 40}) {
      SCOPED_TRACE("a " + std::to_string(na) + " x b " + std::to_string(nb));
      cv::Mat a = RandomUnitRows(na, 64, rng);
      cv::Mat b = RandomUnitRows(nb, 64, rng);
      // b's last row is near a's row 0, and so is an exact copy of it when
      // b has room; a's last row repeats a's row 0.
      cv::Mat near = a.row(0) + 0.1 * RandomUnitRows(1, 64, rng);
      cv::normalize(near, near);
      near.copyTo(b.row(nb - 1));
      if (nb > 2) near.copyTo(b.row(nb / 2));
      if (na > 1) a.row(0).copyTo(a.row(na - 1));
      MatcherOptions o;
      o.max_distance = 2.0;
      o.ratio = 0.95;
      const auto gemm = MatchDescriptors(a, b, o);
      const auto plain = PlainScan(a, b, 0.95f);
      ASSERT_EQ(gemm.size(), plain.size());
      for (size_t k = 0; k < gemm.size(); ++k) {
        EXPECT_EQ(gemm[k].a, plain[k].a);
        EXPECT_EQ(gemm[k].b, plain[k].b);
        EXPECT_NEAR(gemm[k].distance, plain[k].distance, 1e-3);
      }
      const bool tied = nb > 2;
      const bool matched_row0 = !gemm.empty() && gemm[0].a == 0;
      if (tied) {
        EXPECT_FALSE(matched_row0) << "a tie for the nearest passed the ratio test";
      }
    }
  }
}

TEST(MatcherTest, DimensionMismatchIsAnError) {
  std::mt19937 rng(4);
  EXPECT_THROW(MatchDescriptors(RandomUnitRows(3, 64, rng), RandomUnitRows(3, 128, rng), {}),
               std::invalid_argument);
  EXPECT_TRUE(MatchDescriptors(cv::Mat(), RandomUnitRows(3, 64, rng), {}).empty());
}

}  // namespace
}  // namespace ag
