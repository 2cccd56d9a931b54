#include "ground_server/matching/descriptor_matcher.h"

#include <faiss/IndexFlat.h>
#include <omp.h>

#include <cmath>
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
  std::vector<float> norm_b(b.rows);
  for (int j = 0; j < b.rows; ++j) norm_b[j] = static_cast<float>(b.row(j).dot(b.row(j)));
  ab->index.assign(a.rows, -1);
  ab->d1.assign(a.rows, INFINITY);
  ab->d2.assign(a.rows, INFINITY);
  ba->index.assign(b.rows, -1);
  ba->d1.assign(b.rows, INFINITY);
  ba->d2.assign(b.rows, INFINITY);
  for (int i = 0; i < a.rows; ++i) {
    const float norm_a = static_cast<float>(a.row(i).dot(a.row(i)));
    const float* row = dot.ptr<float>(i);
    float d1 = INFINITY, d2 = INFINITY;
    int best = -1;
    for (int j = 0; j < b.rows; ++j) {
      const float d = norm_a + norm_b[j] - 2.0f * row[j];
      if (d < d1) {
        d2 = d1;
        d1 = d;
        best = j;
      } else if (d < d2) {
        d2 = d;
      }
      if (d < ba->d1[j]) {
        ba->d1[j] = d;
        ba->index[j] = i;
      }
    }
    ab->index[i] = best;
    ab->d1[i] = d1;
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
