#include "common/features/xfeat_extractor.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace ag {

namespace {

const std::vector<std::string> kOutputNames = {"output", "1266", "266"};  // desc, logits, rel
constexpr int kLogitChannels = 65;  // 64 positions of an 8x8 cell + "no keypoint"

std::string ShapeString(const cv::Mat& m) {
  std::string s = "[";
  for (int i = 0; i < m.dims; ++i) s += (i ? "," : "") + std::to_string(m.size[i]);
  return s + "]";
}

bool HasShape(const cv::Mat& m, int channels, int cells) {
  return m.dims == 4 && m.size[0] == 1 && m.size[1] == channels && m.size[2] == cells &&
         m.size[3] == cells && m.type() == CV_32F && m.isContinuous();
}

}  // namespace

namespace internal {

float SampleBilinear(const cv::Mat& map, float u, float v) {
  u = std::clamp(u, 0.0f, static_cast<float>(map.cols - 1));
  v = std::clamp(v, 0.0f, static_cast<float>(map.rows - 1));
  const int x0 = static_cast<int>(u);
  const int y0 = static_cast<int>(v);
  const int x1 = std::min(x0 + 1, map.cols - 1);
  const int y1 = std::min(y0 + 1, map.rows - 1);
  const float ax = u - x0;
  const float ay = v - y0;
  const float* r0 = map.ptr<float>(y0);
  const float* r1 = map.ptr<float>(y1);
  return (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x1]) + ay * ((1 - ax) * r1[x0] + ax * r1[x1]);
}

Eigen::Vector2f RefinePeak(const cv::Mat& heat, int x, int y) {
  // Per axis: the vertex of the parabola through the maximum and its two
  // neighbours, -(right - left) / (2 (left + right - 2 centre)).
  auto vertex = [](float before, float centre, float after) {
    const float curvature = before + after - 2 * centre;
    if (!(curvature < 0)) return 0.0f;  // flat (or not a maximum): stay
    return std::clamp(-0.5f * (after - before) / curvature, -0.5f, 0.5f);
  };
  const float* row = heat.ptr<float>(y);
  float dx = 0, dy = 0;
  if (x > 0 && x + 1 < heat.cols) dx = vertex(row[x - 1], row[x], row[x + 1]);
  if (y > 0 && y + 1 < heat.rows) {
    dy = vertex(heat.ptr<float>(y - 1)[x], row[x], heat.ptr<float>(y + 1)[x]);
  }
  return {static_cast<float>(x) + dx, static_cast<float>(y) + dy};
}

XFeatDecoded DecodeXFeat(const float* descriptors, float* logits, const float* reliability,
                         cv::Size cells, cv::Size content, const XFeatDecodeOptions& options) {
  constexpr int kCell = XFeatExtractor::kCell;
  constexpr int kDim = XFeatExtractor::kDim;
  const int plane = cells.area();
  content.width = std::min(content.width, cells.width * kCell);
  content.height = std::min(content.height, cells.height * kCell);
  // Only the cells that cover the content are decoded: a wide image leaves
  // most of the 640x640 input as padding.
  const cv::Rect roi(0, 0, (content.width + kCell - 1) / kCell,
                     (content.height + kCell - 1) / kCell);
  auto channel = [&](int c) { return cv::Mat(cells, CV_32F, logits + c * plane)(roi); };

  // Softmax over the 65 channels, stabilised by the per-cell maximum.
  cv::Mat max_logit = channel(0).clone();
  for (int c = 1; c < kLogitChannels; ++c) cv::max(max_logit, channel(c), max_logit);
  cv::Mat sum = cv::Mat::zeros(roi.size(), CV_32F);
  for (int c = 0; c < kLogitChannels; ++c) {
    cv::Mat ch = channel(c);
    cv::subtract(ch, max_logit, ch);
    cv::exp(ch, ch);
    sum += ch;
  }
  cv::Mat inv_sum;
  cv::divide(1.0, sum, inv_sum);

  // Pixel shuffle: channel c = 8 i + j of cell (h, w) is pixel (8 h + i, 8 w + j).
  cv::Mat heat(roi.height * kCell, roi.width * kCell, CV_32F);
  for (int c = 0; c < kCell * kCell; ++c) {
    const int i = c / kCell;
    const int j = c % kCell;
    cv::Mat ch = channel(c);
    for (int h = 0; h < roi.height; ++h) {
      const float* p = ch.ptr<float>(h);
      const float* inv = inv_sum.ptr<float>(h);
      float* out = heat.ptr<float>(h * kCell + i) + j;
      for (int w = 0; w < roi.width; ++w) out[w * kCell] = p[w] * inv[w];
    }
  }
  // NMS within the content only (a clone, so that padding never suppresses
  // a content pixel; dilate's default border never wins a maximum).
  heat = heat(cv::Rect(cv::Point(0, 0), content)).clone();
  cv::Mat local_max;
  cv::dilate(heat, local_max,
             cv::getStructuringElement(cv::MORPH_RECT,
                                       cv::Size(options.nms_kernel_px, options.nms_kernel_px)));

  struct Candidate {
    float score;
    int x, y;
  };
  std::vector<Candidate> candidates;
  candidates.reserve(4096);
  const cv::Mat reliability_map(cells, CV_32F, const_cast<float*>(reliability));
  const float inv_cell = 1.0f / kCell;
  for (int y = 0; y < heat.rows; ++y) {
    const float* h = heat.ptr<float>(y);
    const float* m = local_max.ptr<float>(y);
    for (int x = 0; x < heat.cols; ++x) {
      if (h[x] > options.detection_threshold && h[x] == m[x]) {
        const float r = SampleBilinear(reliability_map, (x + 0.5f) * inv_cell - 0.5f,
                                       (y + 0.5f) * inv_cell - 0.5f);
        const float score = h[x] * r;
        if (score > 0) candidates.push_back({score, x, y});
      }
    }
  }
  const size_t keep = std::min(candidates.size(), static_cast<size_t>(options.top_k));
  std::partial_sort(candidates.begin(), candidates.begin() + keep, candidates.end(),
                    [](const Candidate& a, const Candidate& b) {
                      if (a.score != b.score) return a.score > b.score;
                      return a.y != b.y ? a.y < b.y : a.x < b.x;
                    });
  candidates.resize(keep);

  // Descriptors: bilinear interpolation of the four neighbouring dense
  // descriptors, each L2-normalised first (as upstream normalises the dense
  // map), then the result normalised again.
  XFeatDecoded out;
  out.keypoints.reserve(keep);
  out.scores.reserve(keep);
  out.descriptors.create(static_cast<int>(keep), kDim, CV_32F);
  for (size_t k = 0; k < keep; ++k) {
    const Candidate& cand = candidates[k];
    out.keypoints.push_back(options.subpixel ? RefinePeak(heat, cand.x, cand.y)
                                             : Eigen::Vector2f(cand.x, cand.y));
    out.scores.push_back(cand.score);
    const float u =
        std::clamp((cand.x + 0.5f) * inv_cell - 0.5f, 0.0f, static_cast<float>(cells.width - 1));
    const float v =
        std::clamp((cand.y + 0.5f) * inv_cell - 0.5f, 0.0f, static_cast<float>(cells.height - 1));
    const int x0 = static_cast<int>(u);
    const int y0 = static_cast<int>(v);
    const int x1 = std::min(x0 + 1, cells.width - 1);
    const int y1 = std::min(y0 + 1, cells.height - 1);
    const float ax = u - x0;
    const float ay = v - y0;
    const int offsets[4] = {y0 * cells.width + x0, y0 * cells.width + x1, y1 * cells.width + x0,
                            y1 * cells.width + x1};
    float weights[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
    for (int n = 0; n < 4; ++n) {
      double norm2 = 0;
      for (int c = 0; c < kDim; ++c) {
        const float d = descriptors[c * plane + offsets[n]];
        norm2 += d * d;
      }
      weights[n] = norm2 > 0 ? weights[n] / static_cast<float>(std::sqrt(norm2)) : 0.0f;
    }
    float* row = out.descriptors.ptr<float>(static_cast<int>(k));
    double norm2 = 0;
    for (int c = 0; c < kDim; ++c) {
      const float* d = descriptors + c * plane;
      const float value = weights[0] * d[offsets[0]] + weights[1] * d[offsets[1]] +
                          weights[2] * d[offsets[2]] + weights[3] * d[offsets[3]];
      row[c] = value;
      norm2 += value * value;
    }
    const float inv_norm = norm2 > 0 ? static_cast<float>(1.0 / std::sqrt(norm2)) : 0.0f;
    for (int c = 0; c < kDim; ++c) row[c] *= inv_norm;
  }
  return out;
}

}  // namespace internal

XFeatExtractor::XFeatExtractor(const std::string& model_path, const FeatureOptions& options)
    : model_path_(model_path), options_(options) {
  const std::string what = "XFeat model '" + model_path + "'";
  try {
    net_ = cv::dnn::readNetFromONNX(model_path);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot load " + what + ": " + e.what());
  }
  if (net_.empty()) throw std::runtime_error("cannot load " + what + ": empty network");
  // One forward pass on a blank input checks the outputs now rather than at
  // the first keyframe (and warms the network up).
  std::vector<cv::Mat> outputs;
  try {
    const int shape[] = {1, 3, kInputSize, kInputSize};
    net_.setInput(cv::Mat(4, shape, CV_32F, cv::Scalar(0.5)), "input");
    net_.forward(outputs, kOutputNames);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(what + " does not run as XFeat (input 'input' [1,3,640,640]; " +
                             "outputs 'output', '1266', '266'): " + e.what());
  }
  const int cells = kInputSize / kCell;
  if (outputs.size() != 3 || !HasShape(outputs[0], kDim, cells) ||
      !HasShape(outputs[1], kLogitChannels, cells) || !HasShape(outputs[2], 1, cells)) {
    std::string got;
    for (const cv::Mat& m : outputs) got += " " + ShapeString(m);
    throw std::runtime_error(what + " has unexpected outputs (want [1,64,80,80] [1,65,80,80] " +
                             "[1,1,80,80] CV_32F; got" + got + ")");
  }
}

internal::XFeatDecoded XFeatExtractor::RunAndDecode(const cv::Mat& input, cv::Size content) const {
  // NCHW blob in [0, 1], RGB order as upstream (the network averages the
  // three channels, so grey input is simply replicated).
  const int shape[] = {1, 3, kInputSize, kInputSize};
  cv::Mat blob(4, shape, CV_32F);
  const int plane = kInputSize * kInputSize;
  auto blob_plane = [&](int c) {
    return cv::Mat(kInputSize, kInputSize, CV_32F, blob.ptr<float>() + c * plane);
  };
  if (input.channels() == 1) {
    input.convertTo(blob_plane(0), CV_32F, 1.0 / 255.0);
    blob_plane(0).copyTo(blob_plane(1));
    blob_plane(0).copyTo(blob_plane(2));
  } else {
    cv::Mat bgr[3];
    cv::split(input, bgr);
    for (int c = 0; c < 3; ++c) bgr[2 - c].convertTo(blob_plane(c), CV_32F, 1.0 / 255.0);
  }

  const cv::Size cells(kInputSize / kCell, kInputSize / kCell);
  internal::XFeatDecodeOptions decode;
  decode.top_k = options_.top_k;
  decode.detection_threshold = static_cast<float>(options_.detection_threshold);
  decode.nms_kernel_px = options_.nms_kernel_px;
  decode.subpixel = options_.subpixel;
  // The outputs share memory with the network's buffers: decode them
  // before another call may run the network again.
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<cv::Mat> outputs;
  net_.setInput(blob, "input");
  net_.forward(outputs, kOutputNames);
  return internal::DecodeXFeat(outputs[0].ptr<float>(), outputs[1].ptr<float>(),
                               outputs[2].ptr<float>(), cells, content, decode);
}

LocalFeatures XFeatExtractor::Extract(const cv::Mat& image) const {
  const cv::Mat img = internal::CheckedImage8U(image, "XFeatExtractor::Extract");
  const cv::Size input(kInputSize, kInputSize);
  LocalFeatures features;
  features.descriptor_type = type();
  if (options_.max_tiles == 1 || (img.cols <= kInputSize && img.rows <= kInputSize)) {
    // One input: the image letterboxed into it (a small one enlarged).
    const Letterbox box = ComputeLetterbox(img.size(), input);
    internal::XFeatDecoded decoded = RunAndDecode(ApplyLetterbox(img, box), box.content);
    features.keypoints.reserve(decoded.keypoints.size());
    for (const Eigen::Vector2f& p_net : decoded.keypoints) {
      features.keypoints.push_back(box.ToOriginal(p_net));
    }
    features.scores = std::move(decoded.scores);
    features.descriptors = decoded.descriptors;
    return features;
  }

  // Several inputs: each tile of the (scaled) image decoded on its own, its
  // keypoints kept where the tile owns them, then the best top_k of all.
  const TileLayout layout = ComputeTileLayout(img.size(), input, options_.max_tiles, kTileOverlap);
  const cv::Mat scaled = ApplyLetterbox(img, layout.scaled);
  struct Candidate {
    float score;
    Eigen::Vector2f p;  // scaled-image px
    size_t tile;
    int row;
  };
  std::vector<internal::XFeatDecoded> decoded(layout.tiles.size());
  std::vector<Candidate> candidates;
  for (size_t t = 0; t < layout.tiles.size(); ++t) {
    const cv::Rect& tile = layout.tiles[t];
    const cv::Mat crop = scaled(tile);
    const Letterbox pad{crop.size(), crop.size(), input, 1.0, 1.0};
    decoded[t] = RunAndDecode(ApplyLetterbox(crop, pad), tile.size());
    for (size_t k = 0; k < decoded[t].keypoints.size(); ++k) {
      const Eigen::Vector2f p = decoded[t].keypoints[k] + Eigen::Vector2f(tile.x, tile.y);
      // Owned by the whole pixel it was detected at (a sub-pixel offset is
      // at most half a pixel), so both tiles decide alike near the split.
      const cv::Point pixel(static_cast<int>(std::lround(p.x())),
                            static_cast<int>(std::lround(p.y())));
      if (!layout.owned[t].contains(pixel)) continue;
      candidates.push_back({decoded[t].scores[k], p, t, static_cast<int>(k)});
    }
  }
  const size_t keep = std::min(candidates.size(), static_cast<size_t>(options_.top_k));
  std::partial_sort(candidates.begin(), candidates.begin() + keep, candidates.end(),
                    [](const Candidate& a, const Candidate& b) {
                      if (a.score != b.score) return a.score > b.score;
                      return a.p.y() != b.p.y() ? a.p.y() < b.p.y() : a.p.x() < b.p.x();
                    });
  features.keypoints.reserve(keep);
  features.scores.reserve(keep);
  features.descriptors.create(static_cast<int>(keep), kDim, CV_32F);
  for (size_t k = 0; k < keep; ++k) {
    const Candidate& c = candidates[k];
    features.keypoints.push_back(layout.scaled.ToOriginal(c.p));
    features.scores.push_back(c.score);
    decoded[c.tile].descriptors.row(c.row).copyTo(features.descriptors.row(static_cast<int>(k)));
  }
  return features;
}

}  // namespace ag
