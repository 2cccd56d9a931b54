#include "common/features/matching.h"

#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>

namespace ag {

std::vector<DescriptorMatch> MatchMutualNearest(const cv::Mat& descriptors_a,
                                                const cv::Mat& descriptors_b,
                                                float min_similarity) {
  std::vector<DescriptorMatch> matches;
  if (descriptors_a.empty() || descriptors_b.empty()) return matches;
  if (descriptors_a.type() != CV_32F || descriptors_b.type() != CV_32F ||
      descriptors_a.cols != descriptors_b.cols) {
    throw std::invalid_argument(
        "MatchMutualNearest: want CV_32F descriptors of equal length, got " +
        std::to_string(descriptors_a.cols) + " and " + std::to_string(descriptors_b.cols));
  }
  const cv::Mat sim = descriptors_a * descriptors_b.t();  // N x M
  std::vector<int> best_a(sim.rows, 0);                   // best b of each a
  std::vector<int> best_b(sim.cols, 0);                   // best a of each b
  std::vector<float> best_b_sim(sim.cols, -2.0f);
  for (int i = 0; i < sim.rows; ++i) {
    const float* s = sim.ptr<float>(i);
    for (int j = 0; j < sim.cols; ++j) {
      if (s[j] > s[best_a[i]]) best_a[i] = j;
      if (s[j] > best_b_sim[j]) {
        best_b_sim[j] = s[j];
        best_b[j] = i;
      }
    }
  }
  for (int i = 0; i < sim.rows; ++i) {
    const int j = best_a[i];
    const float s = sim.at<float>(i, j);
    if (best_b[j] == i && s >= min_similarity) matches.push_back({i, j, s});
  }
  return matches;
}

}  // namespace ag
