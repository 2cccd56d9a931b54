#pragma once

// Local features (keypoints + descriptors) for both agents. The UAV extracts
// them per keyframe and sends them over the link; the UGV extracts its own and
// matches the two sets. Both sides must therefore use the same extractor, so
// the descriptor type travels with the features (LocalFeatures::descriptor_type).

#include <memory>
#include <opencv2/core/mat.hpp>
#include <string>

#include "common/core/error.h"
#include "common/types/keyframe.h"

namespace ag {

/// Options of CreateFeatureExtractor (YAML section `features`).
struct FeatureOptions {
  std::string backend = "xfeat";  ///< "xfeat" (learned, ONNX model) or "sift" (classical)
  /// XFeat ONNX file (tools/fetch_xfeat_model.sh gets it). Empty: $AG_XFEAT_MODEL;
  /// neither set or the file absent: SIFT is used with a warning.
  std::string model_path;
  int top_k = 1024;  ///< keypoints kept per image, highest score first (count)
  double detection_threshold =
      0.05;  ///< XFeat: minimum keypoint probability after softmax ([0, 1])
  int nms_kernel_px =
      5;  ///< XFeat: non-maximum suppression window (odd, network px, 640x640 input)
  /// XFeat: network inputs (640x640) per image at most. An image larger than
  /// one is cut into overlapping tiles at native resolution, or as close to
  /// it as this many allow (1: shrunk into one input, e.g. 1242x375 to
  /// 640x193); each tile costs one network pass (count)
  int max_tiles = 2;
  /// XFeat: refine each keypoint to sub-pixel precision, per axis the vertex of
  /// the parabola through its heatmap maximum and the two neighbours (else
  /// whole pixels, as upstream). Off: on the simulated presets it helped as
  /// often as it hurt; on KITTI it made stereo rows agree better
  /// (tools/evaluation/ACCURACY.md)
  bool subpixel = false;
  double sift_contrast_threshold = 0.04;  ///< SIFT: OpenCV contrastThreshold (lower = more points)

  template <class V>
  void VisitFields(V& v) {
    v("backend", backend);
    v("model_path", model_path);
    v("top_k", top_k);
    v("detection_threshold", detection_threshold);
    v("nms_kernel_px", nms_kernel_px);
    v("max_tiles", max_tiles);
    v("subpixel", subpixel);
    v("sift_contrast_threshold", sift_contrast_threshold);
  }
  void Check() const {
    CheckOption(backend == "xfeat" || backend == "sift", "backend",
                "must be 'xfeat' or 'sift', got '" + backend + "'");
    CheckOption(top_k > 0, "top_k", "must be > 0");
    CheckOption(detection_threshold >= 0 && detection_threshold < 1, "detection_threshold",
                "must be in [0, 1)");
    CheckOption(nms_kernel_px >= 1 && nms_kernel_px % 2 == 1 && nms_kernel_px <= 31,
                "nms_kernel_px", "must be odd, in [1, 31]");
    CheckOption(max_tiles >= 1 && max_tiles <= 64, "max_tiles", "must be in [1, 64]");
    CheckOption(sift_contrast_threshold > 0, "sift_contrast_threshold", "must be > 0");
  }
};

/// Detects keypoints and computes L2-normalised float descriptors.
class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;

  /// Features of an 8-bit grey (CV_8UC1), BGR (CV_8UC3) or BGRA (CV_8UC4)
  /// image of any size. Keypoints are in the image's pixels, sorted by
  /// decreasing score, at most top_k of them. Deterministic. Thread-safe.
  /// Throws std::invalid_argument for an empty image or another pixel type.
  virtual LocalFeatures Extract(const cv::Mat& image) const = 0;

  /// Length of one descriptor (64 for XFeat, 128 for SIFT).
  virtual int descriptor_dim() const = 0;

  /// The descriptor type written into LocalFeatures ("xfeat" or "sift").
  virtual std::string type() const = 0;
};

/// The XFeat model file to use: `option` when not empty, else $AG_XFEAT_MODEL
/// when set and not empty, else "" (no model).
std::string ResolveXFeatModelPath(const std::string& option);

/// Builds the extractor the options ask for. For backend "xfeat" with no
/// model path or a missing model file, logs a loud warning naming the path
/// and how to get the model, and returns SIFT instead. Throws
/// std::runtime_error naming the file when a model file exists but cannot be
/// loaded, and OptionError for invalid options.
std::unique_ptr<FeatureExtractor> CreateFeatureExtractor(const FeatureOptions& options);

namespace internal {

/// An 8-bit grey or BGR view of `image` (converts BGRA; throws
/// std::invalid_argument otherwise). `who` names the caller in the message.
cv::Mat CheckedImage8U(const cv::Mat& image, const char* who);

}  // namespace internal

}  // namespace ag
