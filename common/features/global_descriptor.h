#pragma once

// Global (place) descriptors: one L2-normalised vector per image, compared by
// dot product to retrieve co-visible keyframes.

#include <memory>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/types/keyframe.h"

namespace ag {

/// A user-supplied ONNX place-recognition network (e.g. a MixVPR or NetVLAD
/// export): the image is resized to the input size, scaled to [0, 1],
/// normalised per channel, fed as NCHW float; the output is flattened and
/// L2-normalised.
struct OnnxGlobalDescriptorOptions {
  std::string model_path;   ///< ONNX file (required for backend "onnx")
  std::string input_name;   ///< network input to set; empty: the first input
  std::string output_name;  ///< output to read; empty: the network's last layer
  int input_width = 320;    ///< network input width (px)
  int input_height = 320;   ///< network input height (px)
  bool rgb = true;          ///< feed channels as R, G, B (true) or B, G, R (false)
  std::vector<double> mean = {0.485, 0.456, 0.406};    ///< per fed channel, on [0, 1] values
  std::vector<double> stddev = {0.229, 0.224, 0.225};  ///< per fed channel, on [0, 1] values
  int output_dim = 512;  ///< expected number of output values (descriptor length)

  template <class V>
  void VisitFields(V& v) {
    v("model_path", model_path);
    v("input_name", input_name);
    v("output_name", output_name);
    v("input_width", input_width);
    v("input_height", input_height);
    v("rgb", rgb);
    v("mean", mean);
    v("stddev", stddev);
    v("output_dim", output_dim);
  }
  void Check() const {
    CheckOption(input_width > 0 && input_height > 0, "input_width",
                "input_width and input_height must be > 0");
    CheckOption(mean.size() == 3, "mean", "must have 3 values");
    CheckOption(stddev.size() == 3, "stddev", "must have 3 values");
    for (double s : stddev) CheckOption(s > 0, "stddev", "values must be > 0");
    CheckOption(output_dim > 0, "output_dim", "must be > 0");
  }
};

/// Options of CreateGlobalDescriptorExtractor (YAML section `global_descriptor`).
struct GlobalDescriptorOptions {
  std::string backend = "vlad";  ///< "vlad" (built in, over local descriptors) or "onnx"
  /// VLAD codebook YAML for XFeat / SIFT descriptors; empty: the built-in one
  /// (config/features/vlad_xfeat.yaml, vlad_sift.yaml compiled in).
  std::string vlad_codebook_xfeat;
  std::string vlad_codebook_sift;
  OnnxGlobalDescriptorOptions onnx;  ///< used by backend "onnx"

  template <class V>
  void VisitFields(V& v) {
    v("backend", backend);
    v("vlad_codebook_xfeat", vlad_codebook_xfeat);
    v("vlad_codebook_sift", vlad_codebook_sift);
    v("onnx", onnx);
  }
  void Check() const {
    CheckOption(backend == "vlad" || backend == "onnx", "backend",
                "must be 'vlad' or 'onnx', got '" + backend + "'");
    CheckOption(backend != "onnx" || !onnx.model_path.empty(), "onnx.model_path",
                "must be set for backend 'onnx'");
  }
};

/// Computes one place descriptor per image.
class GlobalDescriptorExtractor {
 public:
  virtual ~GlobalDescriptorExtractor() = default;

  /// The L2-normalised descriptor (dim() values) of an image and its local
  /// features; a backend uses the one it needs. Deterministic. Thread-safe.
  virtual std::vector<float> Compute(const cv::Mat& image, const LocalFeatures& features) const = 0;

  /// Descriptor length.
  virtual int dim() const = 0;

  /// Identifies the descriptor space ("vlad_xfeat_k8", "onnx:<file name>"):
  /// only descriptors of equal type are comparable.
  virtual std::string type() const = 0;
};

/// Builds the extractor the options ask for; `local_descriptor_type` (the
/// FeatureExtractor's type()) picks the VLAD codebook. Throws
/// std::runtime_error naming the file for an unreadable model or codebook,
/// or a codebook of another descriptor type; OptionError for bad options.
std::unique_ptr<GlobalDescriptorExtractor> CreateGlobalDescriptorExtractor(
    const GlobalDescriptorOptions& options, const std::string& local_descriptor_type);

}  // namespace ag
