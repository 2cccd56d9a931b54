#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace ag {

/// How an image was fitted into a fixed network input: scaled (keeping the
/// aspect ratio) to `content` pixels at the top-left corner, the rest padded.
struct Letterbox {
  cv::Size original;   ///< input image size (px)
  cv::Size content;    ///< size of the scaled image inside the network input (px)
  cv::Size target;     ///< network input size (px)
  double scale_x = 1;  ///< content.width / original.width
  double scale_y = 1;  ///< content.height / original.height

  /// Network pixel -> original pixel (pixel centres map onto pixel centres,
  /// as cv::resize samples them), clamped into the original image.
  Eigen::Vector2f ToOriginal(const Eigen::Vector2f& p_net) const;
  /// Original pixel -> network pixel (inverse of ToOriginal, not clamped).
  Eigen::Vector2f ToNetwork(const Eigen::Vector2f& p_original) const;
};

/// The letterbox of an image of size `original` into `target`: the largest
/// scale that fits, sizes rounded to whole pixels (at least 1).
Letterbox ComputeLetterbox(cv::Size original, cv::Size target);

/// `image` (any channel count, 8-bit) resized into `letterbox.content` at the
/// top-left of a `letterbox.target` image; the padding is the image's mean
/// colour so that the artificial border is a weak edge (fewer spurious
/// corners at the content boundary). INTER_AREA when shrinking, bilinear
/// when enlarging.
cv::Mat ApplyLetterbox(const cv::Mat& image, const Letterbox& letterbox);

}  // namespace ag
