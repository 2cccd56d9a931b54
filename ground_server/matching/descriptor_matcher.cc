#include "ground_server/matching/descriptor_matcher.h"

#include <faiss/IndexFlat.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/features2d.hpp>
#include <stdexcept>

#include "common/core/error.h"

namespace ag {
namespace {

// For every row of `query`: the index of its nearest row in `base` and the
// squared L2 distances to the nearest and second nearest.
struct Nearest {
  std::vector<int> index;
  std::vector<float> d1;
  std::vector<float> d2;
};

Nearest SearchFaiss(const cv::Mat& base, const cv::Mat& query, int k, int threads) {
  // FAISS parallelises with OpenMP; the number of threads is a per-thread
  // setting, so this only affects the calling (estimation) thread. One
  // thread is the fastest on 2 cores (17 ms vs 72 ms for 1024 x 1024 with
  // OpenMP's default while other work runs).
  omp_set_num_threads(threads);
  faiss::IndexFlatL2 index(base.cols);
  index.add(base.rows, base.ptr<float>());
  std::vector<float> dist(static_cast<size_t>(query.rows) * k);
  std::vector<faiss::Index::idx_t> ids(static_cast<size_t>(query.rows) * k);
  index.search(query.rows, query.ptr<float>(), k, dist.data(), ids.data());
  Nearest out;
  out.index.resize(query.rows);
  out.d1.resize(query.rows);
  out.d2.resize(query.rows);
  for (int i = 0; i < query.rows; ++i) {
    out.index[i] = static_cast<int>(ids[static_cast<size_t>(i) * k]);
    out.d1[i] = dist[static_cast<size_t>(i) * k];
    out.d2[i] = k > 1 && ids[static_cast<size_t>(i) * k + 1] >= 0
                    ? dist[static_cast<size_t>(i) * k + 1]
                    : INFINITY;
  }
  return out;
}

Nearest SearchOpenCv(const cv::Mat& base, const cv::Mat& query, int k) {
  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, base, knn, k);
  Nearest out;
  out.index.assign(query.rows, -1);
  out.d1.assign(query.rows, INFINITY);
  out.d2.assign(query.rows, INFINITY);
  for (const auto& m : knn) {
    if (m.empty()) continue;
    const int q = m[0].queryIdx;
    out.index[q] = m[0].trainIdx;
    out.d1[q] = m[0].distance * m[0].distance;
    if (m.size() > 1) out.d2[q] = m[1].distance * m[1].distance;
  }
  return out;
}

// The nearest and second nearest of d[0, n) per lane (index j mod kLanes),
// n a multiple of kLanes; see SearchGemm. Out of line, with restrict
// pointers, which is what lets GCC vectorise it.
constexpr int kLanes = 16;
[[gnu::noinline]] void ScanLanes(int n, const float* __restrict d, float* __restrict lane_d1,
                                 float* __restrict lane_d2, int32_t* __restrict lane_j) {
  for (int j0 = 0; j0 < n; j0 += kLanes) {
    for (int l = 0; l < kLanes; ++l) {
      const float v = d[j0 + l];
      const float d1 = lane_d1[l];
      const float d2 = lane_d2[l];
      const int32_t nearest = -static_cast<int32_t>(v < d1);  // all ones when nearer
      const float second = v < d2 ? v : d2;
      lane_d2[l] = v < d1 ? d1 : second;
      lane_j[l] = ((j0 + l) & nearest) | (lane_j[l] & ~nearest);
      lane_d1[l] = v < d1 ? v : d1;
    }
  }
}

// Both directions from one matrix product: the squared distances
// |a_i|^2 + |b_j|^2 - 2 a_i.b_j (as FAISS computes them for large batches),
// nearest and second nearest per row of `a`, nearest per row of `b`. Half
// the work of two searches, and OpenCV's GEMM is vectorised at run time.
void SearchGemm(const cv::Mat& a, const cv::Mat& b, Nearest* ab, Nearest* ba) {
  // OpenCV hands a product to the system BLAS only when its first factor
  // has at least 100 rows (HAL_GEMM_SMALL_MATRIX_THRESH in its
  // core/src/hal_internal.cpp) and computes smaller ones itself, 3-4x
  // slower per row; stage 1 matches about a hundred tracks of a keyframe at
  // a time. So a small `a` goes second and the product is transposed back.
  constexpr int kBlasMinRows = 100;
  cv::Mat dot;
  if (a.rows < kBlasMinRows && b.rows >= kBlasMinRows) {
    cv::Mat dot_t;
    cv::gemm(b, a, 1.0, cv::noArray(), 0.0, dot_t, cv::GEMM_2_T);
    cv::transpose(dot_t, dot);
  } else {
    cv::gemm(a, b, 1.0, cv::noArray(), 0.0, dot, cv::GEMM_2_T);
  }
  const int n = b.rows;
  std::vector<float> norm_b(n);
  for (int j = 0; j < n; ++j) norm_b[j] = static_cast<float>(b.row(j).dot(b.row(j)));
  ab->index.assign(a.rows, -1);
  ab->d1.assign(a.rows, INFINITY);
  ab->d2.assign(a.rows, INFINITY);
  ba->index.assign(n, -1);
  ba->d1.assign(n, INFINITY);
  ba->d2.assign(n, INFINITY);
  // A plain scan of the product, element by element with branches, took
  // as long as computing it (perf, `covisible` seed 1). So no loop below
  // carries a value from one column to the next: each column keeps its own
  // nearest row, and each row's nearest columns are kept per lane (columns
  // j = lane mod kLanes), merged once per row. The selects are written so
  // that compilers vectorise them (an int chosen by a float comparison only
  // as a bit mask): GCC 12 for x86-64, Clang 14 for AArch64; no intrinsics.
  // The result is the plain scan's: first index on ties, and a tie for the
  // nearest makes the second nearest equal to it.
  const int padded = (n + kLanes - 1) / kLanes * kLanes;
  std::vector<float> dist(padded, INFINITY);  // padding: never nearer than anything
  float* const d = dist.data();
  float* const col_d = ba->d1.data();
  int32_t* const col_i = ba->index.data();
  for (int i = 0; i < a.rows; ++i) {
    const float norm_a = static_cast<float>(a.row(i).dot(a.row(i)));
    const float* row = dot.ptr<float>(i);
    for (int j = 0; j < n; ++j) {
      const float v = norm_a + norm_b[j] - 2.0f * row[j];
      d[j] = v;
      const float nearest = col_d[j];
      const int32_t nearer = -static_cast<int32_t>(v < nearest);  // all ones when nearer
      col_d[j] = v < nearest ? v : nearest;
      col_i[j] = (i & nearer) | (col_i[j] & ~nearer);
    }
    float lane_d1[kLanes], lane_d2[kLanes];
    int32_t lane_j[kLanes];
    std::fill(lane_d1, lane_d1 + kLanes, INFINITY);
    std::fill(lane_d2, lane_d2 + kLanes, INFINITY);
    std::fill(lane_j, lane_j + kLanes, -1);
    ScanLanes(padded, d, lane_d1, lane_d2, lane_j);
    int best = -1;  // lane
    for (int l = 0; l < kLanes; ++l) {
      if (lane_j[l] < 0) continue;
      if (best < 0 || lane_d1[l] < lane_d1[best] ||
          (lane_d1[l] == lane_d1[best] && lane_j[l] < lane_j[best])) {
        best = l;
      }
    }
    float d2 = INFINITY;
    for (int l = 0; l < kLanes; ++l) {
      d2 = std::min(d2, lane_d2[l]);
      if (l != best) d2 = std::min(d2, lane_d1[l]);
    }
    ab->index[i] = best >= 0 ? lane_j[best] : -1;
    ab->d1[i] = best >= 0 ? lane_d1[best] : INFINITY;
    ab->d2[i] = d2;
  }
}

}  // namespace

void MatcherOptions::Check() const {
  CheckOption(backend == "gemm" || backend == "faiss" || backend == "opencv", "backend",
              "must be 'gemm', 'faiss' or 'opencv', got '" + backend + "'");
  CheckOption(ratio > 0 && ratio <= 1, "ratio", "must be in (0, 1]");
  CheckOption(max_distance > 0, "max_distance", "must be > 0");
  CheckOption(threads >= 1, "threads", "must be >= 1");
}

std::vector<DescriptorMatch> MatchDescriptors(const cv::Mat& a, const cv::Mat& b,
                                              const MatcherOptions& options) {
  if (a.empty() || b.empty()) return {};
  if (a.type() != CV_32F || b.type() != CV_32F) {
    throw std::invalid_argument("MatchDescriptors: descriptors must be CV_32F");
  }
  if (a.cols != b.cols) {
    throw std::invalid_argument("MatchDescriptors: descriptor dimensions differ (" +
                                std::to_string(a.cols) + " vs " + std::to_string(b.cols) + ")");
  }
  const cv::Mat ac = a.isContinuous() ? a : a.clone();
  const cv::Mat bc = b.isContinuous() ? b : b.clone();
  const bool faiss = options.backend == "faiss";
  const int k = bc.rows > 1 ? 2 : 1;
  Nearest ab, ba;
  if (options.backend == "gemm") {
    SearchGemm(ac, bc, &ab, &ba);
  } else {
    ab = faiss ? SearchFaiss(bc, ac, k, options.threads) : SearchOpenCv(bc, ac, k);
    if (options.mutual)
      ba = faiss ? SearchFaiss(ac, bc, 1, options.threads) : SearchOpenCv(ac, bc, 1);
  }
  const float ratio_sq = static_cast<float>(options.ratio * options.ratio);
  const float max_sq = static_cast<float>(options.max_distance * options.max_distance);
  std::vector<DescriptorMatch> matches;
  for (int i = 0; i < ac.rows; ++i) {
    const int j = ab.index[i];
    if (j < 0 || ab.d1[i] > max_sq) continue;
    if (ab.d1[i] > ratio_sq * ab.d2[i]) continue;
    if (options.mutual && ba.index[j] != i) continue;
    matches.push_back({i, j, std::sqrt(std::max(ab.d1[i], 0.0f))});
  }
  return matches;
}

}  // namespace ag
