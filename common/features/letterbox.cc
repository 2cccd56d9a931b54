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

namespace {

/// Offsets of `count` tiles of length `tile` spread evenly over `length`
/// (first at 0, last ending at `length`).
std::vector<int> TileOffsets(int length, int tile, int count) {
  std::vector<int> offsets(count, 0);
  for (int i = 1; i < count; ++i) {
    offsets[i] =
        static_cast<int>(std::lround(static_cast<double>(i) * (length - tile) / (count - 1)));
  }
  return offsets;
}

/// Tiles needed along one axis of `length` px: 1 when it fits, else enough
/// that neighbours overlap by at least `overlap`.
int TilesAlong(int length, int tile, int overlap) {
  if (length <= tile) return 1;
  return (length - overlap + (tile - overlap) - 1) / (tile - overlap);
}

/// Where each tile's part begins and ends along one axis: the middle of
/// its overlaps with its neighbours, the image's ends at the ends.
std::vector<std::pair<int, int>> OwnedSpans(const std::vector<int>& offsets, int tile, int length) {
  std::vector<std::pair<int, int>> spans(offsets.size());
  for (size_t i = 0; i < offsets.size(); ++i) {
    spans[i].first = i == 0 ? 0 : (offsets[i] + offsets[i - 1] + tile) / 2;
    spans[i].second = i + 1 == offsets.size() ? length : (offsets[i + 1] + offsets[i] + tile) / 2;
  }
  return spans;
}

}  // namespace

TileLayout ComputeTileLayout(cv::Size original, cv::Size input, int max_tiles, int min_overlap) {
  if (original.width <= 0 || original.height <= 0 || input.width <= 0 || input.height <= 0) {
    throw std::invalid_argument("ComputeTileLayout: sizes must be positive");
  }
  if (max_tiles < 1) throw std::invalid_argument("ComputeTileLayout: max_tiles must be >= 1");
  if (min_overlap < 0 || min_overlap >= std::min(input.width, input.height)) {
    throw std::invalid_argument("ComputeTileLayout: overlap must be in [0, input size)");
  }
  // Largest scale over the grids nx x ny <= max_tiles (a grid covers
  // n * input - (n - 1) * overlap px per axis).
  auto reach = [&](int n, int tile) { return n * tile - (n - 1) * min_overlap; };
  double best = 0;
  for (int nx = 1; nx <= max_tiles; ++nx) {
    for (int ny = 1; nx * ny <= max_tiles; ++ny) {
      const double scale =
          std::min({1.0, static_cast<double>(reach(nx, input.width)) / original.width,
                    static_cast<double>(reach(ny, input.height)) / original.height});
      best = std::max(best, scale);
    }
  }
  TileLayout layout;
  Letterbox& scaled = layout.scaled;
  scaled.original = original;
  // Rounded down, so that the scaled image stays within the grid's reach.
  scaled.content.width = std::max(1, static_cast<int>(original.width * best + 1e-9));
  scaled.content.height = std::max(1, static_cast<int>(original.height * best + 1e-9));
  scaled.target = scaled.content;
  scaled.scale_x = static_cast<double>(scaled.content.width) / original.width;
  scaled.scale_y = static_cast<double>(scaled.content.height) / original.height;

  const cv::Size tile(std::min(input.width, scaled.content.width),
                      std::min(input.height, scaled.content.height));
  const std::vector<int> xs = TileOffsets(
      scaled.content.width, tile.width, TilesAlong(scaled.content.width, tile.width, min_overlap));
  const std::vector<int> ys =
      TileOffsets(scaled.content.height, tile.height,
                  TilesAlong(scaled.content.height, tile.height, min_overlap));
  const auto x_spans = OwnedSpans(xs, tile.width, scaled.content.width);
  const auto y_spans = OwnedSpans(ys, tile.height, scaled.content.height);
  for (size_t j = 0; j < ys.size(); ++j) {
    for (size_t i = 0; i < xs.size(); ++i) {
      layout.tiles.emplace_back(xs[i], ys[j], tile.width, tile.height);
      layout.owned.emplace_back(x_spans[i].first, y_spans[j].first,
                                x_spans[i].second - x_spans[i].first,
                                y_spans[j].second - y_spans[j].first);
    }
  }
  return layout;
}

}  // namespace ag
