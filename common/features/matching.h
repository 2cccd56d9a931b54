#pragma once

#include <opencv2/core/mat.hpp>
#include <vector>

namespace ag {

/// One descriptor correspondence.
struct DescriptorMatch {
  int index_a = 0;          ///< row in the first descriptor set
  int index_b = 0;          ///< row in the second descriptor set
  float similarity = 0.0f;  ///< dot product of the two (L2-normalised) rows
};

/// Mutual nearest neighbours by dot product between two sets of
/// L2-normalised descriptors (N x dim and M x dim, CV_32F, equal dim): pairs
/// that are each other's best match with similarity >= `min_similarity`.
/// Exhaustive (one GEMM), sorted by index_a. Ties go to the lower index.
std::vector<DescriptorMatch> MatchMutualNearest(const cv::Mat& descriptors_a,
                                                const cv::Mat& descriptors_b,
                                                float min_similarity = -1.0f);

}  // namespace ag
