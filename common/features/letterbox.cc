#include "common/features/letterbox.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace ag {

Eigen::Vector2f Letterbox::ToOriginal(const Eigen::Vector2f& p_net) const {
  // cv::resize maps destination pixel centre x_d to source x_s with
  // x_s + 0.5 = (x_d + 0.5) / scale.
  const float x = static_cast<float>((p_net.x() + 0.5) / scale_x - 0.5);
  const float y = static_cast<float>((p_net.y() + 0.5) / scale_y - 0.5);
  return {std::clamp(x, 0.0f, static_cast<float>(original.width - 1)),
          std::clamp(y, 0.0f, static_cast<float>(original.height - 1))};
}

Eigen::Vector2f Letterbox::ToNetwork(const Eigen::Vector2f& p_original) const {
  return {static_cast<float>((p_original.x() + 0.5) * scale_x - 0.5),
          static_cast<float>((p_original.y() + 0.5) * scale_y - 0.5)};
}

Letterbox ComputeLetterbox(cv::Size original, cv::Size target) {
  if (original.width <= 0 || original.height <= 0 || target.width <= 0 || target.height <= 0) {
    throw std::invalid_argument("ComputeLetterbox: sizes must be positive");
  }
  const double scale = std::min(static_cast<double>(target.width) / original.width,
                                static_cast<double>(target.height) / original.height);
  Letterbox box;
  box.original = original;
  box.target = target;
  box.content.width =
      std::clamp(static_cast<int>(std::lround(original.width * scale)), 1, target.width);
  box.content.height =
      std::clamp(static_cast<int>(std::lround(original.height * scale)), 1, target.height);
  // Per-axis scales of the rounded sizes: exactly what cv::resize applies.
  box.scale_x = static_cast<double>(box.content.width) / original.width;
  box.scale_y = static_cast<double>(box.content.height) / original.height;
  return box;
}

cv::Mat ApplyLetterbox(const cv::Mat& image, const Letterbox& letterbox) {
  if (image.size() != letterbox.original) {
    throw std::invalid_argument("ApplyLetterbox: image size differs from the letterbox's");
  }
  cv::Mat out(letterbox.target, image.type(), cv::mean(image));
  cv::Mat content = out(cv::Rect(cv::Point(0, 0), letterbox.content));
  if (letterbox.content == image.size()) {
    image.copyTo(content);
  } else {
    const bool shrink = letterbox.scale_x < 1.0 && letterbox.scale_y < 1.0;
    cv::resize(image, content, letterbox.content, 0, 0, shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  return out;
}

}  // namespace ag
