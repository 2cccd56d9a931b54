#include "common/features/sift_extractor.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace ag {

SiftExtractor::SiftExtractor(const FeatureOptions& options) : options_(options) {}

LocalFeatures SiftExtractor::Extract(const cv::Mat& image) const {
  cv::Mat grey = internal::CheckedImage8U(image, "SiftExtractor::Extract");
  if (grey.channels() == 3) cv::cvtColor(grey, grey, cv::COLOR_BGR2GRAY);

  // A detector per call: Feature2D::detectAndCompute is not const, and
  // creating SIFT costs nothing next to running it.
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(options_.top_k, 3, options_.sift_contrast_threshold);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat raw;
  sift->detectAndCompute(grey, cv::noArray(), keypoints, raw);

  // OpenCV collects keypoints from parallel workers in no fixed order, and
  // its nfeatures cut keeps ties: a total order makes the result deterministic.
  std::vector<int> order(keypoints.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    const cv::KeyPoint& ka = keypoints[a];
    const cv::KeyPoint& kb = keypoints[b];
    if (ka.response != kb.response) return ka.response > kb.response;
    if (ka.pt.y != kb.pt.y) return ka.pt.y < kb.pt.y;
    if (ka.pt.x != kb.pt.x) return ka.pt.x < kb.pt.x;
    if (ka.size != kb.size) return ka.size < kb.size;
    return ka.angle < kb.angle;
  });
  order.resize(std::min(order.size(), static_cast<size_t>(options_.top_k)));

  LocalFeatures features;
  features.descriptor_type = type();
  features.descriptors.create(static_cast<int>(order.size()), kDim, CV_32F);
  for (size_t i = 0; i < order.size(); ++i) {
    const cv::KeyPoint& kp = keypoints[order[i]];
    features.keypoints.emplace_back(kp.pt.x, kp.pt.y);
    features.scores.push_back(kp.response);
    const float* in = raw.ptr<float>(order[i]);
    float* out = features.descriptors.ptr<float>(static_cast<int>(i));
    double l1 = 0;
    for (int c = 0; c < kDim; ++c) l1 += std::abs(in[c]);
    const double inv = l1 > 0 ? 1.0 / l1 : 0.0;
    for (int c = 0; c < kDim; ++c) out[c] = static_cast<float>(std::sqrt(std::abs(in[c]) * inv));
  }
  return features;
}

}  // namespace ag
