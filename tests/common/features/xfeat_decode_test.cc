// XFeat's post-processing against a slow, obviously-correct reference, the
// letterbox mapping, the tile layout, determinism, and the model path
// resolution.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "common/features/letterbox.h"
#include "common/features/xfeat_extractor.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

constexpr int kCells = 80;  // 640 / 8
constexpr int kPlane = kCells * kCells;
constexpr const char* kKittiLeft0 =
    "data/kitti_raw_2011_09_26_drive_0001_mini/2011_09_26/2011_09_26_drive_0001_sync/"
    "image_02/data/0000000000.png";

/// Raw network outputs with the statistics of real ones: most cells have one
/// dominant keypoint position, some only the "no keypoint" channel.
struct RawOutputs {
  std::vector<float> descriptors, logits, reliability;
};

RawOutputs RandomOutputs(uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  RawOutputs raw;
  raw.descriptors.resize(64 * kPlane);
  raw.logits.resize(65 * kPlane);
  raw.reliability.resize(kPlane);
  for (float& d : raw.descriptors) d = normal(rng);
  for (float& l : raw.logits) l = normal(rng);
  for (int i = 0; i < kPlane; ++i) {
    const int channel = uniform(rng) < 0.7f ? static_cast<int>(uniform(rng) * 64) : 64;
    raw.logits[channel * kPlane + i] += 2.0f + 4.0f * uniform(rng);
    raw.reliability[i] = 0.01f + 0.99f * uniform(rng);
  }
  return raw;
}

/// The post-processing written pixel by pixel, straight from the upstream
/// description (double precision, no OpenCV).
internal::XFeatDecoded ReferenceDecode(const RawOutputs& raw, cv::Size content,
                                       const internal::XFeatDecodeOptions& options) {
  auto heat = [&](int x, int y) {
    const int cell = (y / 8) * kCells + x / 8;
    const int channel = (y % 8) * 8 + x % 8;
    double max_logit = -1e30;
    for (int c = 0; c < 65; ++c)
      max_logit = std::max<double>(max_logit, raw.logits[c * kPlane + cell]);
    double sum = 0;
    for (int c = 0; c < 65; ++c) sum += std::exp(raw.logits[c * kPlane + cell] - max_logit);
    return std::exp(raw.logits[channel * kPlane + cell] - max_logit) / sum;
  };
  std::vector<double> h(static_cast<size_t>(content.area()));
  for (int y = 0; y < content.height; ++y) {
    for (int x = 0; x < content.width; ++x) h[y * content.width + x] = heat(x, y);
  }
  // Bilinear sample of a 80x80 map at cell coordinates, clamped.
  auto bilinear = [&](const float* map, double u, double v) {
    u = std::clamp(u, 0.0, kCells - 1.0);
    v = std::clamp(v, 0.0, kCells - 1.0);
    const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
    const int x1 = std::min(x0 + 1, kCells - 1), y1 = std::min(y0 + 1, kCells - 1);
    const double ax = u - x0, ay = v - y0;
    return (1 - ay) * ((1 - ax) * map[y0 * kCells + x0] + ax * map[y0 * kCells + x1]) +
           ay * ((1 - ax) * map[y1 * kCells + x0] + ax * map[y1 * kCells + x1]);
  };
  struct Kp {
    double score;
    int x, y;
  };
  std::vector<Kp> kps;
  const int r = options.nms_kernel_px / 2;
  for (int y = 0; y < content.height; ++y) {
    for (int x = 0; x < content.width; ++x) {
      const double v = h[y * content.width + x];
      if (v <= options.detection_threshold) continue;
      bool is_max = true;
      for (int dy = -r; dy <= r && is_max; ++dy) {
        for (int dx = -r; dx <= r; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= content.width || yy >= content.height) continue;
          if (h[yy * content.width + xx] > v) is_max = false;
        }
      }
      if (!is_max) continue;
      const double u = (x + 0.5) / 8 - 0.5, w = (y + 0.5) / 8 - 0.5;
      kps.push_back({v * bilinear(raw.reliability.data(), u, w), x, y});
    }
  }
  std::sort(kps.begin(), kps.end(), [](const Kp& a, const Kp& b) {
    if (a.score != b.score) return a.score > b.score;
    return a.y != b.y ? a.y < b.y : a.x < b.x;
  });
  if (static_cast<int>(kps.size()) > options.top_k) kps.resize(options.top_k);

  internal::XFeatDecoded out;
  out.descriptors.create(static_cast<int>(kps.size()), 64, CV_32F);
  for (size_t k = 0; k < kps.size(); ++k) {
    out.keypoints.emplace_back(kps[k].x, kps[k].y);
    out.scores.push_back(static_cast<float>(kps[k].score));
    // Bilinear interpolation of the L2-normalised dense descriptors.
    const double u = std::clamp((kps[k].x + 0.5) / 8 - 0.5, 0.0, kCells - 1.0);
    const double v = std::clamp((kps[k].y + 0.5) / 8 - 0.5, 0.0, kCells - 1.0);
    std::vector<double> d(64, 0.0);
    for (int corner = 0; corner < 4; ++corner) {
      const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
      const int cx = std::min(x0 + corner % 2, kCells - 1);
      const int cy = std::min(y0 + corner / 2, kCells - 1);
      const double wx = corner % 2 ? u - x0 : 1 - (u - x0);
      const double wy = corner / 2 ? v - y0 : 1 - (v - y0);
      double norm = 0;
      for (int c = 0; c < 64; ++c)
        norm += std::pow(raw.descriptors[c * kPlane + cy * kCells + cx], 2);
      norm = std::sqrt(norm);
      for (int c = 0; c < 64; ++c) {
        d[c] += wx * wy * raw.descriptors[c * kPlane + cy * kCells + cx] / norm;
      }
    }
    double norm = 0;
    for (double x : d) norm += x * x;
    for (int c = 0; c < 64; ++c) {
      out.descriptors.at<float>(static_cast<int>(k), c) =
          static_cast<float>(d[c] / std::sqrt(norm));
    }
  }
  return out;
}

/// Same keypoints, scores and descriptors. The reference ranks by double
/// scores, the library by float ones, so keypoints whose scores tie within
/// float rounding may swap places: ranks are compared by score, keypoints by
/// position.
void ExpectSameDecoding(const internal::XFeatDecoded& got, const internal::XFeatDecoded& want) {
  ASSERT_EQ(got.keypoints.size(), want.keypoints.size());
  ASSERT_EQ(got.descriptors.rows, want.descriptors.rows);
  const size_t n = want.keypoints.size();
  std::map<std::pair<float, float>, size_t> want_index;
  for (size_t k = 0; k < n; ++k) want_index[{want.keypoints[k].x(), want.keypoints[k].y()}] = k;
  const float last_score = n > 0 ? want.scores.back() : 0.0f;
  int swapped = 0;
  for (size_t k = 0; k < n; ++k) {
    ASSERT_NEAR(got.scores[k], want.scores[k], 1e-5 * want.scores[k]) << "rank " << k;
    if (k > 0) {
      ASSERT_GE(got.scores[k - 1], got.scores[k]) << "rank " << k;
    }
    swapped += got.keypoints[k] != want.keypoints[k];
    const auto it = want_index.find({got.keypoints[k].x(), got.keypoints[k].y()});
    if (it == want_index.end()) {
      // Only a near-tie at the top-k cut may select another keypoint.
      ASSERT_NEAR(got.scores[k], last_score, 1e-5 * last_score) << "rank " << k;
      continue;
    }
    const size_t j = it->second;
    ASSERT_NEAR(got.scores[k], want.scores[j], 1e-5 * want.scores[j]) << "rank " << k;
    ASSERT_LT(cv::norm(got.descriptors.row(static_cast<int>(k)),
                       want.descriptors.row(static_cast<int>(j)), cv::NORM_INF),
              1e-5)
        << "rank " << k;
  }
  EXPECT_LE(swapped, static_cast<int>(n / 100)) << "more than near-ties differ in rank";
}

TEST(XFeatDecodeTest, MatchesThePixelByPixelReference) {
  struct Case {
    cv::Size content;
    int top_k;
    float threshold;
    int nms;
  };
  // Full input, a wide letterbox (KITTI-like), a tall one, other settings.
  const Case cases[] = {{{640, 640}, 1024, 0.05f, 5},
                        {{640, 193}, 100000, 0.05f, 5},
                        {{301, 640}, 256, 0.05f, 5},
                        {{640, 480}, 512, 0.2f, 3},
                        {{500, 500}, 128, 0.01f, 7}};
  uint32_t seed = 1;
  for (const Case& c : cases) {
    SCOPED_TRACE("content " + std::to_string(c.content.width) + "x" +
                 std::to_string(c.content.height));
    const RawOutputs raw = RandomOutputs(seed++);
    internal::XFeatDecodeOptions options;
    options.top_k = c.top_k;
    options.detection_threshold = c.threshold;
    options.nms_kernel_px = c.nms;
    options.subpixel = false;  // the reference's whole pixels; RefinePeak below
    const internal::XFeatDecoded want = ReferenceDecode(raw, c.content, options);
    std::vector<float> logits = raw.logits;  // scratch for DecodeXFeat
    const internal::XFeatDecoded got =
        internal::DecodeXFeat(raw.descriptors.data(), logits.data(), raw.reliability.data(),
                              cv::Size(kCells, kCells), c.content, options);
    ASSERT_GT(want.keypoints.size(), 50u);
    ExpectSameDecoding(got, want);
    for (const Eigen::Vector2f& p : got.keypoints) {
      EXPECT_LT(p.x(), c.content.width);
      EXPECT_LT(p.y(), c.content.height);
    }
  }
}

TEST(XFeatDecodeTest, RefinePeakFindsTheVertexWithinHalfAPixel) {
  // A paraboloid's vertex exactly; a Gaussian's (the shape of a softmax of
  // quadratic logits) to a tenth of a pixel.
  const Eigen::Vector2f centre(10.3f, 7.8f);
  cv::Mat parabola(16, 20, CV_32F), gauss(16, 20, CV_32F);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 20; ++x) {
      const float d2 = (Eigen::Vector2f(x, y) - centre).squaredNorm();
      parabola.at<float>(y, x) = 100.0f - d2;
      gauss.at<float>(y, x) = std::exp(-d2 / (2 * 1.2f * 1.2f));
    }
  }
  EXPECT_LT((internal::RefinePeak(parabola, 10, 8) - centre).norm(), 1e-4f);
  EXPECT_LT((internal::RefinePeak(gauss, 10, 8) - centre).norm(), 0.1f);
  // Never more than half a pixel from the maximum it starts at.
  const Eigen::Vector2f off = internal::RefinePeak(parabola, 12, 5);
  EXPECT_FLOAT_EQ(off.x(), 11.5f);
  EXPECT_FLOAT_EQ(off.y(), 5.5f);
  // On the map's edge, and where flat, the whole pixel stays.
  EXPECT_EQ(internal::RefinePeak(parabola, 0, 0), Eigen::Vector2f(0, 0));
  EXPECT_EQ(internal::RefinePeak(parabola, 19, 15), Eigen::Vector2f(19, 15));
  EXPECT_EQ(internal::RefinePeak(cv::Mat(5, 5, CV_32F, cv::Scalar(0.3f)), 2, 2),
            Eigen::Vector2f(2, 2));

  // Decoding with it moves keypoints by at most half a pixel per axis and
  // changes nothing else.
  const RawOutputs raw = RandomOutputs(9);
  internal::XFeatDecodeOptions options;
  options.subpixel = false;
  std::vector<float> scratch = raw.logits;
  const internal::XFeatDecoded whole =
      internal::DecodeXFeat(raw.descriptors.data(), scratch.data(), raw.reliability.data(),
                            cv::Size(kCells, kCells), {640, 480}, options);
  options.subpixel = true;
  scratch = raw.logits;
  const internal::XFeatDecoded refined =
      internal::DecodeXFeat(raw.descriptors.data(), scratch.data(), raw.reliability.data(),
                            cv::Size(kCells, kCells), {640, 480}, options);
  ASSERT_EQ(refined.keypoints.size(), whole.keypoints.size());
  ASSERT_GT(whole.keypoints.size(), 50u);
  EXPECT_EQ(refined.scores, whole.scores);
  EXPECT_EQ(cv::norm(refined.descriptors, whole.descriptors, cv::NORM_INF), 0.0);
  int moved = 0;
  for (size_t k = 0; k < whole.keypoints.size(); ++k) {
    const Eigen::Vector2f d = refined.keypoints[k] - whole.keypoints[k];
    EXPECT_LE(d.cwiseAbs().maxCoeff(), 0.5f);
    moved += d != Eigen::Vector2f::Zero();
  }
  EXPECT_GT(moved, static_cast<int>(whole.keypoints.size() / 2));
}

TEST(XFeatDecodeTest, SampleBilinearInterpolatesAndClamps) {
  cv::Mat map = (cv::Mat_<float>(2, 3) << 0, 1, 2, 10, 11, 12);
  EXPECT_FLOAT_EQ(internal::SampleBilinear(map, 0, 0), 0);
  EXPECT_FLOAT_EQ(internal::SampleBilinear(map, 1.5f, 0.5f), 6.5f);
  EXPECT_FLOAT_EQ(internal::SampleBilinear(map, -3, -3), 0);  // clamped
  EXPECT_FLOAT_EQ(internal::SampleBilinear(map, 9, 9), 12);   // clamped
}

TEST(LetterboxTest, ScalesToFitAndMapsPixelCentres) {
  const Letterbox wide = ComputeLetterbox({1242, 375}, {640, 640});
  EXPECT_EQ(wide.content, cv::Size(640, 193));
  const Letterbox tall = ComputeLetterbox({300, 700}, {640, 640});
  EXPECT_EQ(tall.content, cv::Size(274, 640));
  const Letterbox small = ComputeLetterbox({64, 48}, {640, 640});
  EXPECT_EQ(small.content, cv::Size(640, 480));
  for (const Letterbox& box : {wide, tall, small}) {
    // Round trip, and the content's outer pixel centres on the image's.
    for (const Eigen::Vector2f& p :
         {Eigen::Vector2f(0, 0), Eigen::Vector2f(10.25f, 20.5f),
          Eigen::Vector2f(box.original.width - 1.0f, box.original.height - 1.0f)}) {
      EXPECT_LT((box.ToOriginal(box.ToNetwork(p)) - p).norm(), 1e-3f);
    }
    const Eigen::Vector2f first = box.ToNetwork({-0.5f, -0.5f});
    const Eigen::Vector2f last =
        box.ToNetwork({box.original.width - 0.5f, box.original.height - 0.5f});
    EXPECT_NEAR(first.x(), -0.5f, 1e-4f);
    EXPECT_NEAR(first.y(), -0.5f, 1e-4f);
    EXPECT_NEAR(last.x(), box.content.width - 0.5f, 1e-3f);
    EXPECT_NEAR(last.y(), box.content.height - 0.5f, 1e-3f);
    // Clamped into the image.
    const Eigen::Vector2f far = box.ToOriginal({1000, 1000});
    EXPECT_EQ(far, Eigen::Vector2f(box.original.width - 1.0f, box.original.height - 1.0f));
  }
}

TEST(LetterboxTest, ContentAtTopLeftPaddingIsTheMeanColour) {
  cv::Mat image(100, 300, CV_8UC3, cv::Scalar(10, 20, 30));
  image(cv::Rect(0, 0, 150, 100)).setTo(cv::Scalar(50, 60, 70));
  const Letterbox box = ComputeLetterbox(image.size(), {640, 640});
  const cv::Mat out = ApplyLetterbox(image, box);
  ASSERT_EQ(out.size(), cv::Size(640, 640));
  EXPECT_EQ(out.at<cv::Vec3b>(10, 10), cv::Vec3b(50, 60, 70));    // content, left half
  EXPECT_EQ(out.at<cv::Vec3b>(10, 600), cv::Vec3b(10, 20, 30));   // content, right half
  EXPECT_EQ(out.at<cv::Vec3b>(600, 300), cv::Vec3b(30, 40, 50));  // padding: the mean
  EXPECT_THROW(ApplyLetterbox(image, ComputeLetterbox({10, 10}, {640, 640})),
               std::invalid_argument);
}

// The tiles of an image larger than the input: the properties every layout
// must have, on the sizes cameras have and on random ones.
void ExpectValidLayout(const TileLayout& layout, cv::Size original, int max_tiles, int overlap) {
  SCOPED_TRACE(testing::Message() << original << " max_tiles " << max_tiles);
  const cv::Size scaled = layout.scaled.content;
  EXPECT_EQ(layout.scaled.original, original);
  EXPECT_EQ(layout.scaled.target, scaled);
  EXPECT_LE(layout.scaled.scale_x, 1.0);
  EXPECT_LE(layout.scaled.scale_y, 1.0);
  EXPECT_NEAR(layout.scaled.scale_x, layout.scaled.scale_y,
              1.0 / std::min(scaled.width, scaled.height));
  ASSERT_GE(layout.tiles.size(), 1u);
  EXPECT_LE(static_cast<int>(layout.tiles.size()), max_tiles);
  ASSERT_EQ(layout.owned.size(), layout.tiles.size());
  cv::Mat owners(scaled, CV_32S, cv::Scalar(0));
  const cv::Rect image(cv::Point(0, 0), scaled);
  for (size_t t = 0; t < layout.tiles.size(); ++t) {
    const cv::Rect& tile = layout.tiles[t];
    const cv::Rect& owned = layout.owned[t];
    EXPECT_EQ(tile & image, tile);
    EXPECT_LE(tile.width, 640);
    EXPECT_LE(tile.height, 640);
    EXPECT_EQ(owned & tile, owned);
    // Half an overlap between an owned part and an edge the tile shares.
    if (owned.x > 0) {
      EXPECT_GE(owned.x - tile.x, overlap / 2);
    }
    if (owned.y > 0) {
      EXPECT_GE(owned.y - tile.y, overlap / 2);
    }
    if (owned.br().x < scaled.width) {
      EXPECT_GE(tile.br().x - owned.br().x, overlap / 2);
    }
    if (owned.br().y < scaled.height) {
      EXPECT_GE(tile.br().y - owned.br().y, overlap / 2);
    }
    owners(owned) += 1;
  }
  double lo = 0, hi = 0;
  cv::minMaxLoc(owners, &lo, &hi);
  EXPECT_EQ(lo, 1) << "a pixel no tile owns";
  EXPECT_EQ(hi, 1) << "a pixel two tiles own";
}

TEST(TileLayoutTest, NativeResolutionWhereTheTilesAllowIt) {
  struct Case {
    cv::Size original;
    int max_tiles;
    cv::Size scaled;
    size_t tiles;
  };
  const std::vector<Case> cases = {
      {{1242, 375}, 2, {1242, 375}, 2},    // KITTI: native in two
      {{1242, 375}, 4, {1242, 375}, 2},    // no more tiles than needed
      {{1242, 375}, 1, {640, 193}, 1},     // one: the letterbox's scale
      {{1280, 720}, 6, {1280, 720}, 6},    // HD: 3 x 2
      {{1280, 720}, 4, {1248, 702}, 4},    // 2 x 2 reach 1248 px
      {{1280, 720}, 2, {1137, 640}, 2},    // as large as two allow
      {{1920, 1080}, 6, {1856, 1044}, 6},  // full HD: 3 x 2 reach 1856 px
      {{1920, 1080}, 2, {1137, 640}, 2},  {{300, 700}, 2, {300, 700}, 2},  // tall: one column
      {{640, 480}, 2, {640, 480}, 1},  // fits: one tile, as it is
  };
  for (const Case& c : cases) {
    const TileLayout layout = ComputeTileLayout(c.original, {640, 640}, c.max_tiles, 32);
    EXPECT_EQ(layout.scaled.content, c.scaled) << c.original << " max_tiles " << c.max_tiles;
    EXPECT_EQ(layout.tiles.size(), c.tiles) << c.original << " max_tiles " << c.max_tiles;
    ExpectValidLayout(layout, c.original, c.max_tiles, 32);
  }
  // KITTI's two tiles: the halves of the image, overlapping by 38 px and
  // split at their middle.
  const TileLayout kitti = ComputeTileLayout({1242, 375}, {640, 640}, 2, 32);
  EXPECT_EQ(kitti.tiles[0], cv::Rect(0, 0, 640, 375));
  EXPECT_EQ(kitti.tiles[1], cv::Rect(602, 0, 640, 375));
  EXPECT_EQ(kitti.owned[0], cv::Rect(0, 0, 621, 375));
  EXPECT_EQ(kitti.owned[1], cv::Rect(621, 0, 621, 375));

  std::mt19937 rng(7);
  std::uniform_int_distribution<int> side(1, 4000), tiles(1, 9), overlap(0, 200);
  for (int i = 0; i < 300; ++i) {
    const cv::Size original(side(rng), side(rng));
    const int max_tiles = tiles(rng), min_overlap = overlap(rng);
    const TileLayout layout = ComputeTileLayout(original, {640, 640}, max_tiles, min_overlap);
    ExpectValidLayout(layout, original, max_tiles, min_overlap);
    // Neighbouring tiles overlap by at least min_overlap.
    std::vector<int> xs, ys;
    for (const cv::Rect& tile : layout.tiles) {
      xs.push_back(tile.x);
      ys.push_back(tile.y);
    }
    for (std::vector<int>* offsets : {&xs, &ys}) {
      std::sort(offsets->begin(), offsets->end());
      offsets->erase(std::unique(offsets->begin(), offsets->end()), offsets->end());
    }
    EXPECT_EQ(xs.size() * ys.size(), layout.tiles.size()) << original << ": not a grid";
    for (size_t k = 1; k < xs.size(); ++k) {
      EXPECT_GE(xs[k - 1] + layout.tiles[0].width - xs[k], min_overlap) << original;
    }
    for (size_t k = 1; k < ys.size(); ++k) {
      EXPECT_GE(ys[k - 1] + layout.tiles[0].height - ys[k], min_overlap) << original;
    }
  }
  EXPECT_THROW(ComputeTileLayout({0, 10}, {640, 640}, 2, 32), std::invalid_argument);
  EXPECT_THROW(ComputeTileLayout({100, 10}, {640, 640}, 0, 32), std::invalid_argument);
  EXPECT_THROW(ComputeTileLayout({100, 10}, {640, 640}, 2, 640), std::invalid_argument);
}

TEST(XFeatExtractorTest, DeterministicGreyEqualsReplicatedBgrNoKeypointInPadding) {
  AG_REQUIRE_SHARED(model, "models/xfeat.onnx");
  AG_REQUIRE_SHARED(image_path, kKittiLeft0);
  FeatureOptions options;
  options.top_k = 1024;
  options.max_tiles = 1;  // the letterbox; tiles: XFeatTest.TilesKeepKittisNativeResolution
  const XFeatExtractor xfeat(model, options);
  const cv::Mat grey = cv::imread(image_path, cv::IMREAD_GRAYSCALE);
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  const LocalFeatures a = xfeat.Extract(grey);
  const LocalFeatures b = xfeat.Extract(grey);
  const LocalFeatures c = xfeat.Extract(bgr);
  ASSERT_EQ(a.size(), 1024u);
  EXPECT_EQ(a.descriptor_type, "xfeat");
  for (const LocalFeatures* other : {&b, &c}) {
    ASSERT_EQ(other->size(), a.size());
    EXPECT_EQ(other->keypoints, a.keypoints);
    EXPECT_EQ(other->scores, a.scores);
    EXPECT_EQ(cv::norm(other->descriptors, a.descriptors, cv::NORM_INF), 0.0);
  }
  // Every keypoint maps back into the letterbox's content, not its padding.
  const Letterbox box = ComputeLetterbox(grey.size(), {640, 640});
  for (const Eigen::Vector2f& k : a.keypoints) {
    const Eigen::Vector2f n = box.ToNetwork(k);
    EXPECT_GT(n.y(), -0.5f);
    EXPECT_LT(n.y(), box.content.height - 0.5f);
    EXPECT_LT(n.x(), box.content.width - 0.5f);
  }
  // BGRA is accepted, other pixel types are not.
  cv::Mat bgra;
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  EXPECT_EQ(xfeat.Extract(bgra).keypoints, a.keypoints);
  EXPECT_THROW(xfeat.Extract(cv::Mat(10, 10, CV_32F)), std::invalid_argument);
  EXPECT_THROW(xfeat.Extract(cv::Mat()), std::invalid_argument);
  // Tiny images are enlarged into the input and still give keypoints.
  cv::Mat tiny;
  cv::resize(grey(cv::Rect(500, 150, 120, 80)), tiny, {120, 80});
  const LocalFeatures t = xfeat.Extract(tiny);
  EXPECT_GT(t.size(), 10u);
  for (const Eigen::Vector2f& k : t.keypoints) {
    EXPECT_TRUE(k.x() >= 0 && k.y() >= 0 && k.x() <= 119 && k.y() <= 79);
  }
}

/// Sets an environment variable for one scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value != nullptr) {
      setenv(name, value, 1);
    } else {
      unsetenv(name);
    }
  }
  ~ScopedEnv() {
    if (old_.empty()) {
      unsetenv(name_.c_str());
    } else {
      setenv(name_.c_str(), old_.c_str(), 1);
    }
  }

 private:
  std::string name_, old_;
};

TEST(FeatureFactoryTest, ModelPathIsTheOptionElseTheEnvironment) {
  {
    ScopedEnv env("AG_XFEAT_MODEL", "/from/env.onnx");
    EXPECT_EQ(ResolveXFeatModelPath(""), "/from/env.onnx");
    EXPECT_EQ(ResolveXFeatModelPath("/from/option.onnx"), "/from/option.onnx");
  }
  {
    ScopedEnv env("AG_XFEAT_MODEL", nullptr);
    EXPECT_EQ(ResolveXFeatModelPath(""), "");
    FeatureOptions options;  // xfeat, no path anywhere: SIFT
    EXPECT_EQ(CreateFeatureExtractor(options)->type(), "sift");
  }
  const auto model = test::SharedPath("models/xfeat.onnx");
  if (model) {
    ScopedEnv env("AG_XFEAT_MODEL", model->c_str());
    const auto extractor = CreateFeatureExtractor(FeatureOptions{});
    EXPECT_EQ(extractor->type(), "xfeat");
    EXPECT_EQ(extractor->descriptor_dim(), 64);
  }
  FeatureOptions bad;
  bad.top_k = 0;
  EXPECT_THROW(CreateFeatureExtractor(bad), OptionError);
  bad = FeatureOptions{};
  bad.nms_kernel_px = 4;
  EXPECT_THROW(CreateFeatureExtractor(bad), OptionError);
  bad = FeatureOptions{};
  bad.backend = "orb";
  EXPECT_THROW(CreateFeatureExtractor(bad), OptionError);
}

}  // namespace
}  // namespace ag
