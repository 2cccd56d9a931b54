#pragma once

// XFeat (Potje et al., "XFeat: Accelerated Features for Lightweight Image
// Matching", CVPR 2024) through OpenCV DNN. The post-processing reproduces the
// authors' XFeat.detectAndCompute (verlab/accelerated_features,
// modules/xfeat.py): softmax over 65 logits per 8x8 cell, pixel-shuffle of the
// 64 keypoint channels into a full-resolution heatmap, 5x5 NMS above a
// threshold, score = heatmap x reliability, top-k, descriptors sampled from
// the 1/8-resolution map and L2-normalised. Beyond upstream: keypoints are
// refined to sub-pixel precision (FeatureOptions::subpixel), and images
// larger than the fixed input are cut into tiles (FeatureOptions::max_tiles).

#include <mutex>
#include <opencv2/dnn.hpp>
#include <string>

#include "common/features/feature_extractor.h"
#include "common/features/letterbox.h"

namespace ag {

namespace internal {
struct XFeatDecoded;
}  // namespace internal

/// XFeat keypoints and 64-D descriptors. The model has a fixed 640x640
/// input. An image that fits is letterboxed into it (a smaller one
/// enlarged); a larger one is cut into up to FeatureOptions::max_tiles
/// overlapping tiles at native resolution (or as close to it as that many
/// allow), each run through the network, their keypoints merged by score;
/// with max_tiles 1 it is shrunk into one input. Keypoints are mapped back
/// into the image's pixels.
class XFeatExtractor : public FeatureExtractor {
 public:
  static constexpr int kInputSize = 640;  ///< network input width = height (px)
  static constexpr int kCell = 8;         ///< output stride (px)
  static constexpr int kDim = 64;         ///< descriptor length
  /// Least overlap of neighbouring tiles (px): each tile keeps keypoints at
  /// least half of it away from an edge it shares, where the network sees
  /// padding instead of the neighbour's pixels.
  static constexpr int kTileOverlap = 32;

  /// Loads the ONNX model; throws std::runtime_error naming `model_path`
  /// when it is absent or cannot be loaded, or lacks the expected outputs.
  XFeatExtractor(const std::string& model_path, const FeatureOptions& options);

  LocalFeatures Extract(const cv::Mat& image) const override;
  int descriptor_dim() const override { return kDim; }
  std::string type() const override { return "xfeat"; }

 private:
  /// One network pass over a 640x640 `input` whose top-left `content` is
  /// image; keypoints in input px.
  internal::XFeatDecoded RunAndDecode(const cv::Mat& input, cv::Size content) const;

  std::string model_path_;
  FeatureOptions options_;
  mutable std::mutex mutex_;  ///< cv::dnn::Net::forward is not re-entrant
  mutable cv::dnn::Net net_;
};

namespace internal {

/// Post-processing settings of DecodeXFeat.
struct XFeatDecodeOptions {
  int top_k = 1024;
  float detection_threshold = 0.05f;
  int nms_kernel_px = 5;
  bool subpixel = false;  ///< keypoints refined by RefinePeak (else whole network pixels)
};

/// Keypoints in network pixels, sorted by decreasing score.
struct XFeatDecoded {
  std::vector<Eigen::Vector2f> keypoints;  ///< network px (whole, or refined by RefinePeak)
  std::vector<float> scores;
  cv::Mat descriptors;  ///< N x 64 CV_32F, rows L2-normalised
};

/// Decodes raw XFeat outputs of one image (all CHW, cells = H/8 x W/8 of
/// the network input): `descriptors` 64 x cells, `logits` 65 x cells,
/// `reliability` 1 x cells. Only keypoints inside `content` (network px,
/// from the top-left) are kept. `logits` is used as scratch (overwritten).
/// Ties in score are broken by (y, x) so that the result is deterministic.
XFeatDecoded DecodeXFeat(const float* descriptors, float* logits, const float* reliability,
                         cv::Size cells, cv::Size content, const XFeatDecodeOptions& options);

/// The sub-pixel position of a keypoint heatmap's local maximum at whole
/// pixel (x, y): per axis, the vertex of the parabola through it and its two
/// neighbours, within half a pixel of (x, y); an axis on the map's edge or
/// without curvature keeps its whole pixel.
Eigen::Vector2f RefinePeak(const cv::Mat& heat, int x, int y);

/// Bilinear sample of a single-channel CV_32F map at continuous position
/// (u, v) in map pixels (centre of pixel (0,0) is (0,0)), clamped to the map.
float SampleBilinear(const cv::Mat& map, float u, float v);

}  // namespace internal

}  // namespace ag
