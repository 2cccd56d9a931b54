#pragma once

#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace ag {

/// A putative correspondence between row `a` of one descriptor set and row
/// `b` of the other.
struct DescriptorMatch {
  int a = 0;
  int b = 0;
  float distance = 0;  ///< L2 distance of the (unit-norm) descriptors
};

/// Mutual nearest neighbours with Lowe's ratio test, as the paper matches
/// air and ground descriptors (with FAISS).
struct MatcherOptions {
  /// "gemm" (one OpenCV matrix product for both directions, the fastest),
  /// "faiss" (exact flat L2) or "opencv" (BFMatcher); all exact
  std::string backend = "gemm";
  double ratio = 0.9;         ///< nearest / second-nearest distance must be below this
  bool mutual = true;         ///< keep only pairs that are each other's nearest
  double max_distance = 1.2;  ///< reject matches farther than this (unit descriptors: [0, 2])
  int threads = 1;            ///< FAISS OpenMP threads for the calling thread

  template <class V>
  void VisitFields(V& v) {
    v("backend", backend);
    v("ratio", ratio);
    v("mutual", mutual);
    v("max_distance", max_distance);
    v("threads", threads);
  }
  void Check() const;
};

/// Matches two descriptor sets (rows, CV_32F, same number of columns).
/// Exact: every backend searches exhaustively; the result is sorted by `a`.
/// Throws std::invalid_argument naming the problem when the types or
/// dimensions differ (callers check descriptor_type before matching).
std::vector<DescriptorMatch> MatchDescriptors(const cv::Mat& a, const cv::Mat& b,
                                              const MatcherOptions& options);

}  // namespace ag
