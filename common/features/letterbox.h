#pragma once

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <vector>

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

/// How an image larger than a fixed network input is covered by several
/// inputs ("tiles") at native resolution, or as close to it as `max_tiles`
/// allows: the image is scaled by at most 1 (`scaled`, whose content and
/// target are the scaled size, so ApplyLetterbox gives the scaled image) and
/// cut into overlapping tiles of at most the input size.
struct TileLayout {
  Letterbox scaled;  ///< original -> scaled image (no padding: target == content)
  /// Tiles in scaled-image pixels, row by row, each within the input size.
  std::vector<cv::Rect> tiles;
  /// Per tile, the part of the scaled image whose keypoints it keeps: the
  /// tiles' overlaps split at their middle, so the parts are disjoint and
  /// cover the scaled image, and each lies at least half an overlap inside
  /// its tile's edges where it has a neighbour.
  std::vector<cv::Rect> owned;
};

/// The layout of an image of size `original` over at most `max_tiles`
/// inputs of size `input`, neighbouring tiles overlapping by at least
/// `min_overlap` px: the largest scale (at most 1) for which some grid of
/// nx x ny <= max_tiles tiles covers the scaled image (fewest tiles among
/// equal scales). Throws std::invalid_argument for non-positive sizes,
/// max_tiles < 1 or an overlap not smaller than the input.
TileLayout ComputeTileLayout(cv::Size original, cv::Size input, int max_tiles, int min_overlap);

}  // namespace ag
