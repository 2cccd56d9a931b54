#pragma once

#include "common/features/feature_extractor.h"

namespace ag {

/// Classical fallback: OpenCV SIFT keypoints (Lowe 2004) with RootSIFT
/// descriptors (Arandjelovic and Zisserman, "Three things everyone should know
/// to improve object retrieval", CVPR 2012): L1-normalise, square root, which
/// leaves each 128-D row with unit L2 norm, so dot products behave like the
/// Hellinger kernel. Keypoints are ranked by detector response.
class SiftExtractor : public FeatureExtractor {
 public:
  static constexpr int kDim = 128;  ///< descriptor length

  explicit SiftExtractor(const FeatureOptions& options);

  LocalFeatures Extract(const cv::Mat& image) const override;
  int descriptor_dim() const override { return kDim; }
  std::string type() const override { return "sift"; }

 private:
  FeatureOptions options_;
};

}  // namespace ag
