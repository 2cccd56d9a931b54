#pragma once

#include <mutex>
#include <opencv2/dnn.hpp>

#include "common/features/global_descriptor.h"

namespace ag {

/// A global descriptor network in ONNX, run by OpenCV DNN.
class OnnxGlobalDescriptor : public GlobalDescriptorExtractor {
 public:
  /// Loads the model and runs it once on a blank input to check that it
  /// yields options.output_dim values; throws std::runtime_error naming the
  /// file otherwise.
  explicit OnnxGlobalDescriptor(const OnnxGlobalDescriptorOptions& options);

  /// Ignores `features`. `image`: 8-bit grey, BGR or BGRA.
  std::vector<float> Compute(const cv::Mat& image, const LocalFeatures& features) const override;
  int dim() const override { return options_.output_dim; }
  std::string type() const override;

  /// The NCHW float blob fed to the network for `image` (exposed for tests).
  cv::Mat MakeBlob(const cv::Mat& image) const;

 private:
  std::vector<float> Run(const cv::Mat& blob) const;

  OnnxGlobalDescriptorOptions options_;
  mutable std::mutex mutex_;  ///< cv::dnn::Net::forward is not re-entrant
  mutable cv::dnn::Net net_;
};

}  // namespace ag
