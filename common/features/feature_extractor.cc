#include "common/features/feature_extractor.h"

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "common/config/options.h"
#include "common/features/sift_extractor.h"
#include "common/features/xfeat_extractor.h"

namespace ag {

namespace internal {

cv::Mat CheckedImage8U(const cv::Mat& image, const char* who) {
  if (image.empty()) throw std::invalid_argument(std::string(who) + ": empty image");
  if (image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)) {
    throw std::invalid_argument(std::string(who) +
                                ": want an 8-bit grey, BGR or BGRA image, got type " +
                                std::to_string(image.type()));
  }
  if (image.channels() != 4) return image;
  cv::Mat bgr;
  cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  return bgr;
}

}  // namespace internal

std::string ResolveXFeatModelPath(const std::string& option) {
  if (!option.empty()) return option;
  const char* env = std::getenv("AG_XFEAT_MODEL");
  return env != nullptr ? std::string(env) : std::string();
}

std::unique_ptr<FeatureExtractor> CreateFeatureExtractor(const FeatureOptions& options) {
  CheckOptions(options);
  if (options.backend == "sift") return std::make_unique<SiftExtractor>(options);

  const std::string path = ResolveXFeatModelPath(options.model_path);
  std::error_code ec;
  if (path.empty() || !std::filesystem::exists(path, ec)) {
    const std::string which = path.empty()
                                  ? std::string(
                                        "no model path given (features.model_path is empty and "
                                        "$AG_XFEAT_MODEL is not set)")
                                  : "model file '" + path + "' does not exist";
    spdlog::warn(
        "*** XFEAT MODEL MISSING: {}. FALLING BACK TO SIFT: descriptors are of type 'sift' and "
        "match only other SIFT features, with fewer correct matches across viewpoints. Get the "
        "model with tools/fetch_xfeat_model.sh (or tools/fetch_xfeat_model.sh --from FILE), "
        "then set features.model_path or AG_XFEAT_MODEL to models/xfeat.onnx. ***",
        which);
    return std::make_unique<SiftExtractor>(options);
  }
  return std::make_unique<XFeatExtractor>(path, options);
}

}  // namespace ag
