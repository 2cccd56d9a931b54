#include "tools/sim/texture.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/core/error.h"
#include "tools/sim/random.h"

namespace ag {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3f;
using Footprint = SurfaceTexture::Footprint;

// ---------------------------------------------------------------------------
// Hashing and band-limited gradient noise.

inline uint32_t Fmix32(uint32_t h) {
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return h;
}

inline uint32_t HashCell(int32_t x, int32_t y, uint32_t seed) {
  uint32_t h = seed ^ (static_cast<uint32_t>(x) * 0x8da6b343u);
  h = (h ^ (h >> 15)) * 0x2c1b3c6du;
  h ^= static_cast<uint32_t>(y) * 0xd8163841u;
  return Fmix32(h);
}

inline float UnitFloat(uint32_t h) { return static_cast<float>(h >> 8) * (1.0f / 16777216.0f); }

inline float Clamp01(float x) { return x < 0.0f ? 0.0f : (x > 1.0f ? 1.0f : x); }

/// Eight gradient directions, looked up without branches.
constexpr float kGradients[8][2] = {{1.0f, 1.0f},        {1.0f, -1.0f},       {-1.0f, 1.0f},
                                    {-1.0f, -1.0f},      {1.41421356f, 0.0f}, {-1.41421356f, 0.0f},
                                    {0.0f, 1.41421356f}, {0.0f, -1.41421356f}};

inline float Grad(uint32_t h, float x, float y) {
  const float* g = kGradients[h & 7u];
  return g[0] * x + g[1] * y;
}

/// Lattice hash for the noise: x and y are pre-multiplied once per call, so
/// each corner costs one multiply (the full HashCell is kept for decals).
inline uint32_t CornerHash(uint32_t hx, uint32_t hy) {
  uint32_t h = hx ^ hy;
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  return h >> 29;  // the top bits are the best mixed
}

/// Hash of a decal cell: one multiply-xorshift round is enough to decide
/// whether a cell holds a decal (its parameters are then mixed further).
inline uint32_t DecalCellHash(int32_t x, int32_t y, uint32_t seed) {
  uint32_t h =
      (static_cast<uint32_t>(x) * 0x8da6b343u) ^ (static_cast<uint32_t>(y) * 0xd8163841u) ^ seed;
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  return h ^ (h >> 16);
}

/// Perlin gradient noise, zero mean, standard deviation ~0.2.
float GradientNoise(double x, double y, uint32_t seed) {
  const double fx = std::floor(x);
  const double fy = std::floor(y);
  const auto ix = static_cast<uint32_t>(static_cast<int32_t>(fx));
  const auto iy = static_cast<uint32_t>(static_cast<int32_t>(fy));
  const auto tx = static_cast<float>(x - fx);
  const auto ty = static_cast<float>(y - fy);
  const float u = tx * tx * tx * (tx * (tx * 6.0f - 15.0f) + 10.0f);
  const float v = ty * ty * ty * (ty * (ty * 6.0f - 15.0f) + 10.0f);
  const uint32_t hx0 = (ix * 0x8da6b343u) ^ seed, hx1 = ((ix + 1u) * 0x8da6b343u) ^ seed;
  const uint32_t hy0 = iy * 0xd8163841u, hy1 = (iy + 1u) * 0xd8163841u;
  const float n00 = Grad(CornerHash(hx0, hy0), tx, ty);
  const float n10 = Grad(CornerHash(hx1, hy0), tx - 1.0f, ty);
  const float n01 = Grad(CornerHash(hx0, hy1), tx, ty - 1.0f);
  const float n11 = Grad(CornerHash(hx1, hy1), tx - 1.0f, ty - 1.0f);
  const float a = n00 + u * (n10 - n00);
  const float b = n01 + u * (n11 - n01);
  return a + v * (b - a);
}

constexpr float kNoiseStdInv = 4.6f;  // 1 / std of GradientNoise (measured)

/// Octave rotations so the lattices of successive octaves do not line up.
const std::array<std::array<float, 2>, 16>& OctaveRotations() {
  static const std::array<std::array<float, 2>, 16> table = [] {
    std::array<std::array<float, 2>, 16> t{};
    for (int i = 0; i < 16; ++i) {
      t[i] = {static_cast<float>(std::cos(0.61 * i + 0.3)),
              static_cast<float>(std::sin(0.61 * i + 0.3))};
    }
    return t;
  }();
  return table;
}

/// Fractal noise with unit standard deviation at full detail, band-limited to
/// the footprint: octave i (wavelength largest_m / 2^i) is weighted 1 when its
/// wavelength is >= 3 footprints and 0 below 2 footprints (Nyquist), so a far
/// view sees the local average, as a camera does. An anisotropic footprint
/// (`fp.major` longer than `fp.minor`) averages each octave over taps along
/// the long axis, as few as its wavelength needs.
float FilteredFbm(const Vector2d& uv, const Footprint& fp, float largest_m, int octaves, float gain,
                  uint32_t seed, float stretch_u = 1.0f) {
  const auto& rot = OctaveRotations();
  float sum = 0.0f;
  float amp = 1.0f;
  float total = 0.0f;
  double s = largest_m;
  const float fw_tap = std::max(fp.minor, fp.major_len / static_cast<float>(fp.taps));
  // Octave i's wavelength s is largest_m / 2^i exactly, and a quotient
  // scaled by a power of two is the same quotient scaled, rounding included
  // (these are far from overflow and subnormals), so wavelength / footprint
  // and 2 |major| / wavelength need one division each, not one per octave.
  float s_over_fw = largest_m / fw_tap;
  double major_over_s = 2.0 * fp.major_len / static_cast<double>(largest_m);
  for (int i = 0; i < octaves; ++i) {
    total += amp * amp;
    const float w = Clamp01(s_over_fw - 2.0f);
    if (w > 0.0f) {
      const auto& r = rot[i & 15];
      // clamp(ceil(major_over_s), 1, fp.taps), counted without branches.
      int taps = 1;
      for (int k = 1; k < fp.taps; ++k) taps += major_over_s > k ? 1 : 0;
      float value = 0.0f;
      for (int k = 0; k < taps; ++k) {
        const double f = taps == 1 ? 0.0 : (k + 0.5) / taps - 0.5;
        const double u0 = (uv.x() + f * fp.major.x()) * stretch_u;
        const double v0 = uv.y() + f * fp.major.y();
        const double x = (r[0] * u0 - r[1] * v0) / s + 17.31 * i;
        const double y = (r[1] * u0 + r[0] * v0) / s - 9.17 * i;
        value += GradientNoise(x, y, seed + 0x9e3779b9u * static_cast<uint32_t>(i + 1));
      }
      sum += amp * w * value / static_cast<float>(taps);
    }
    amp *= gain;
    s *= 0.5;
    s_over_fw *= 0.5f;
    major_over_s *= 2.0;
  }
  return sum * kNoiseStdInv / std::sqrt(total);
}

/// Isotropic footprint of width fw.
float FilteredFbm(const Vector2d& uv, float fw, float largest_m, int octaves, float gain,
                  uint32_t seed, float stretch_u = 1.0f) {
  Footprint fp;
  fp.minor = fw;
  fp.major_len = fw;
  return FilteredFbm(uv, fp, largest_m, octaves, gain, seed, stretch_u);
}

/// Box-filtered coverage of a shape from its signed distance (negative
/// inside) at filter width fw.
inline float Coverage(float sd, float fw) { return Clamp01(0.5f - sd / fw); }

/// Weight of a feature of size `size_m` under filter width fw: 1 when the
/// feature is resolved, fading to 0 when it is far below a footprint.
inline float Resolved(float size_m, float fw) { return Clamp01(size_m / fw - 0.5f); }

Vector3f Lerp(const Vector3f& a, const Vector3f& b, float t) { return a + t * (b - a); }

Vector3f Hsv(float h, float s, float v) {  // h in [0, 1)
  const float h6 = (h - std::floor(h)) * 6.0f;
  const float c = v * s;
  const float x = c * (1.0f - std::fabs(std::fmod(h6, 2.0f) - 1.0f));
  Vector3f rgb;
  if (h6 < 1)
    rgb = {c, x, 0};
  else if (h6 < 2)
    rgb = {x, c, 0};
  else if (h6 < 3)
    rgb = {0, c, x};
  else if (h6 < 4)
    rgb = {0, x, c};
  else if (h6 < 5)
    rgb = {x, 0, c};
  else
    rgb = {c, 0, x};
  return rgb + Vector3f::Constant(v - c);
}

Vector3f Jitter(const Vector3f& c, SimRandom& rng, float amount) {
  Vector3f out;
  const float brightness = 1.0f + amount * static_cast<float>(rng.Uniform(-1.0, 1.0));
  for (int i = 0; i < 3; ++i) {
    out[i] =
        c[i] * brightness * (1.0f + 0.3f * amount * static_cast<float>(rng.Uniform(-1.0, 1.0)));
  }
  return out.cwiseMax(0.01f).cwiseMin(0.95f);
}

/// 64 directions for decal orientations (no trigonometry per sample).
const std::array<std::array<float, 2>, 64>& DecalDirections() {
  static const std::array<std::array<float, 2>, 64> table = [] {
    std::array<std::array<float, 2>, 64> t{};
    for (int i = 0; i < 64; ++i) {
      t[i] = {static_cast<float>(std::cos(2.0 * M_PI * i / 64.0)),
              static_cast<float>(std::sin(2.0 * M_PI * i / 64.0))};
    }
    return t;
  }();
  return table;
}

enum DecalShape : uint32_t {
  kDisc = 1,
  kRing = 2,
  kRect = 4,
  kStroke = 8,
  kText = 16,
  kBlob = 32,
};

const std::array<Vector3f, 8>& PaintPalette() {
  static const std::array<Vector3f, 8> palette = {
      Vector3f(0.80f, 0.80f, 0.78f), Vector3f(0.75f, 0.55f, 0.05f), Vector3f(0.55f, 0.06f, 0.05f),
      Vector3f(0.05f, 0.15f, 0.50f), Vector3f(0.03f, 0.03f, 0.03f), Vector3f(0.80f, 0.30f, 0.03f),
      Vector3f(0.10f, 0.40f, 0.12f), Vector3f(0.60f, 0.60f, 0.65f)};
  return palette;
}

/// Ground region recipes: indices into GroundRegion().
enum GroundRegionType { kAsphalt = 0, kGrass, kGravel, kPavers, kDirt, kNumGroundRegions };

}  // namespace

// ---------------------------------------------------------------------------
// TextureImages

TextureImages TextureImages::LoadFolder(const std::string& dir, double texel_m) {
  namespace fs = std::filesystem;
  if (!fs::is_directory(dir)) {
    throw InputError(InputErrorKind::kMissingFile, dir, 0, "texture folder does not exist");
  }
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tif" ||
        ext == ".tiff") {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());  // directory order is not deterministic
  if (files.empty())
    throw InputError(InputErrorKind::kMissingFile, dir, 0, "no image in texture folder");
  TextureImages out;
  out.texel_m_ = texel_m;
  for (const std::string& file : files) {
    cv::Mat img = cv::imread(file, cv::IMREAD_COLOR);
    if (img.empty() || img.cols < 8 || img.rows < 8) {
      throw InputError(InputErrorKind::kMalformedRow, file, 0, "cannot decode texture image");
    }
    std::vector<Level> levels;
    cv::Mat current = img;
    while (true) {
      Level level;
      level.width = current.cols;
      level.height = current.rows;
      level.texels.resize(static_cast<size_t>(level.width) * level.height);
      for (int y = 0; y < current.rows; ++y) {
        for (int x = 0; x < current.cols; ++x) {
          const cv::Vec3b bgr = current.at<cv::Vec3b>(y, x);
          Vector3f rgb;
          for (int c = 0; c < 3; ++c)
            rgb[c] = std::pow(bgr[2 - c] / 255.0f, 2.2f);  // sRGB -> linear
          level.texels[static_cast<size_t>(y) * level.width + x] = rgb * 0.85f;
        }
      }
      levels.push_back(std::move(level));
      if (current.cols < 4 || current.rows < 4) break;
      cv::Mat next;
      cv::pyrDown(current, next);
      current = next;
    }
    out.images_.push_back(std::move(levels));
  }
  return out;
}

Vector3f TextureImages::Sample(size_t index, const Vector2d& uv, double footprint_m) const {
  const auto& levels = images_[index % images_.size()];
  const double fw_texels = std::max(footprint_m / texel_m_, 1.0);
  const double lod = std::min(std::log2(fw_texels), static_cast<double>(levels.size() - 1));
  const int l0 = static_cast<int>(std::floor(lod));
  const int l1 = std::min(l0 + 1, static_cast<int>(levels.size()) - 1);
  const auto frac = static_cast<float>(lod - l0);
  auto bilinear = [&](const Level& level, double scale) {
    const double x = uv.x() / (texel_m_ * scale) - 0.5;
    const double y = -uv.y() / (texel_m_ * scale) - 0.5;  // v up, image rows down
    const double fx = std::floor(x);
    const double fy = std::floor(y);
    const auto tx = static_cast<float>(x - fx);
    const auto ty = static_cast<float>(y - fy);
    auto wrap = [](int64_t i, int n) { return static_cast<int>(((i % n) + n) % n); };
    const int x0 = wrap(static_cast<int64_t>(fx), level.width);
    const int x1 = wrap(static_cast<int64_t>(fx) + 1, level.width);
    const int y0 = wrap(static_cast<int64_t>(fy), level.height);
    const int y1 = wrap(static_cast<int64_t>(fy) + 1, level.height);
    const auto& t = level.texels;
    const Vector3f a = Lerp(t[y0 * level.width + x0], t[y0 * level.width + x1], tx);
    const Vector3f b = Lerp(t[y1 * level.width + x0], t[y1 * level.width + x1], tx);
    return Lerp(a, b, ty);
  };
  Vector3f c0 = bilinear(levels[l0], std::ldexp(1.0, l0));
  if (l1 == l0 || frac <= 0.0f) return c0;
  return Lerp(c0, bilinear(levels[l1], std::ldexp(1.0, l1)), frac);
}

// ---------------------------------------------------------------------------
// SurfaceTexture recipes

SurfaceTexture::GroundRegion SurfaceTexture::MakeGroundRegion(int type, uint64_t seed) {
  SimRandom rng(seed, "ground_region", static_cast<uint64_t>(type));
  SurfaceTexture::GroundRegion r;
  r.mix_m = static_cast<float>(rng.Uniform(2.0, 5.0));
  switch (type) {
    case kAsphalt:
      r.a = Vector3f::Constant(static_cast<float>(rng.Uniform(0.07, 0.12)));
      r.b = r.a * 1.4f;
      r.detail = 0.16f;
      r.detail_scale_m = 0.12f;
      r.octaves = 5;
      r.speckle = 0.6f;
      r.speckle_m = 0.01f;
      break;
    case kGrass:
      r.a = Hsv(static_cast<float>(rng.Uniform(0.2, 0.28)), 0.65f,
                static_cast<float>(rng.Uniform(0.08, 0.13)));
      r.b = Hsv(static_cast<float>(rng.Uniform(0.12, 0.2)), 0.55f,
                static_cast<float>(rng.Uniform(0.16, 0.24)));
      r.detail = 0.25f;
      r.detail_scale_m = 0.15f;
      r.octaves = 5;
      r.speckle = 0.7f;
      r.speckle_m = 0.012f;
      break;
    case kGravel:
      r.a = Vector3f::Constant(static_cast<float>(rng.Uniform(0.2, 0.3)));
      r.b = Hsv(0.1f, 0.2f, static_cast<float>(rng.Uniform(0.25, 0.35)));
      r.detail = 0.12f;
      r.detail_scale_m = 0.3f;
      r.octaves = 5;
      r.speckle = 0.8f;
      r.speckle_m = 0.025f;
      break;
    case kPavers:
      r.a =
          Hsv(static_cast<float>(rng.Uniform(0.0, 0.08)), static_cast<float>(rng.Uniform(0.1, 0.4)),
              static_cast<float>(rng.Uniform(0.2, 0.35)));
      r.b = r.a * 0.75f;
      r.detail = 0.15f;
      r.detail_scale_m = 0.1f;
      r.octaves = 5;
      r.tile_w = static_cast<float>(rng.Uniform(0.2, 0.4));
      r.tile_h = r.tile_w * static_cast<float>(rng.Uniform(0.5, 1.0));
      r.joint = 0.008f;
      r.speckle = 0.2f;
      r.speckle_m = 0.01f;
      break;
    default:  // dirt
      r.a = Hsv(static_cast<float>(rng.Uniform(0.06, 0.1)), 0.45f,
                static_cast<float>(rng.Uniform(0.14, 0.22)));
      r.b = r.a * 0.7f;
      r.detail = 0.2f;
      r.detail_scale_m = 0.3f;
      r.octaves = 6;
      r.speckle = 0.5f;
      r.speckle_m = 0.018f;
      break;
  }
  return r;
}

SurfaceTexture::SurfaceTexture(MaterialKind kind, uint64_t seed)
    : kind_(kind),
      seed_(static_cast<uint32_t>(MixBits64(seed))),
      image_pick_(MixBits64(seed ^ 0x5bd1e995ULL)) {
  SimRandom rng(seed, "surface_texture");
  auto add_decals = [&](float cell_m, float probability, float contrast, uint32_t kinds,
                        bool paint) {
    DecalLayer layer;
    layer.cell_m = cell_m * static_cast<float>(rng.Uniform(0.8, 1.25));
    layer.probability = probability * static_cast<float>(rng.Uniform(0.6, 1.3));
    layer.contrast = contrast;
    for (uint32_t bit = 1; bit <= kBlob; bit <<= 1) {
      if (kinds & bit) layer.shapes[layer.n_shapes++] = bit;
    }
    layer.paint = paint;
    decals_.push_back(layer);
  };
  auto add_windows = [&]() {
    window_w_ = static_cast<float>(rng.Uniform(0.9, 1.5));
    window_h_ = static_cast<float>(rng.Uniform(1.1, 1.7));
    window_pitch_u_ = window_w_ + static_cast<float>(rng.Uniform(0.8, 2.2));
    window_pitch_v_ = window_h_ + static_cast<float>(rng.Uniform(1.2, 1.8));
    window_sill_ = static_cast<float>(rng.Uniform(0.9, 1.4));
  };
  switch (kind) {
    case MaterialKind::kGround:
      // Regions are picked per point in GroundBase; these are ground-wide decals.
      mix_scale_m_ = static_cast<float>(rng.Uniform(14.0, 22.0));
      for (int i = 0; i < kNumGroundRegions; ++i) regions_.push_back(MakeGroundRegion(i, seed));
      std::rotate(regions_.begin(), regions_.begin() + rng.UniformInt(0, kNumGroundRegions - 1),
                  regions_.end());
      add_decals(0.25f, 0.10f, 0.5f, kDisc | kRect | kBlob, false);  // leaves, litter, pebbles
      add_decals(2.5f, 0.22f, 0.8f, kText | kStroke | kRect, true);  // stencils, markings
      add_decals(4.0f, 0.35f, 0.45f, kBlob | kDisc | kRing, false);  // stains, manholes
      add_decals(9.0f, 0.35f, 0.35f, kBlob | kRect, false);          // large patches
      break;
    case MaterialKind::kBrick: {
      const float hue = static_cast<float>(rng.Uniform(0.0, 0.07));
      color_a_ = Hsv(hue, static_cast<float>(rng.Uniform(0.45, 0.7)),
                     static_cast<float>(rng.Uniform(0.25, 0.45)));
      color_b_ = Jitter(color_a_ * 0.7f, rng, 0.2f);
      cell_w_ = static_cast<float>(rng.Uniform(0.2, 0.3));
      cell_h_ = static_cast<float>(rng.Uniform(0.065, 0.09));
      joint_m_ = 0.012f;
      cell_variation_ = static_cast<float>(rng.Uniform(0.12, 0.25));
      running_bond_ = 0.5f;
      joint_color_ = Vector3f::Constant(static_cast<float>(rng.Uniform(0.3, 0.55)));
      detail_contrast_ = 0.12f;
      detail_scale_m_ = 0.2f;
      detail_octaves_ = 5;
      add_windows();
      add_decals(3.0f, 0.35f, 0.45f, kBlob, false);
      add_decals(3.5f, 0.30f, 0.9f, kText | kRect, true);
      break;
    }
    case MaterialKind::kPlaster:
      color_a_ = Hsv(static_cast<float>(rng.Uniform()), static_cast<float>(rng.Uniform(0.1, 0.45)),
                     static_cast<float>(rng.Uniform(0.4, 0.75)));
      color_b_ = Jitter(color_a_ * 0.8f, rng, 0.15f);
      mix_scale_m_ = static_cast<float>(rng.Uniform(2.0, 6.0));
      detail_contrast_ = 0.1f;
      detail_scale_m_ = 1.0f;
      detail_octaves_ = 7;
      add_windows();
      add_decals(2.0f, 0.4f, 0.4f, kBlob | kStroke, false);
      add_decals(2.5f, 0.35f, 0.9f, kText | kStroke | kRect, true);
      add_decals(0.6f, 0.15f, 0.35f, kDisc | kStroke, false);
      break;
    case MaterialKind::kConcrete:
      color_a_ = Vector3f::Constant(static_cast<float>(rng.Uniform(0.28, 0.45)));
      color_a_ = Jitter(color_a_, rng, 0.08f);
      color_b_ = Jitter(color_a_ * 0.8f, rng, 0.1f);
      mix_scale_m_ = static_cast<float>(rng.Uniform(1.5, 4.0));
      cell_w_ = static_cast<float>(rng.Uniform(1.2, 2.5));
      cell_h_ = static_cast<float>(rng.Uniform(0.6, 1.2));
      joint_m_ = 0.015f;
      cell_variation_ = 0.08f;
      joint_color_ = color_a_ * 0.55f;
      detail_contrast_ = 0.18f;
      detail_scale_m_ = 0.8f;
      detail_octaves_ = 7;
      add_decals(1.6f, 0.45f, 0.9f, kStroke | kText | kBlob, true);  // graffiti, tags
      add_decals(1.0f, 0.35f, 0.4f, kBlob | kStroke, false);
      add_decals(0.4f, 0.4f, 0.6f, kDisc, false);  // tie holes
      break;
    case MaterialKind::kRoof:
      color_a_ = Vector3f::Constant(static_cast<float>(rng.Uniform(0.12, 0.35)));
      color_a_ = Jitter(color_a_, rng, 0.1f);
      color_b_ = Jitter(color_a_ * 1.2f, rng, 0.1f);
      mix_scale_m_ = static_cast<float>(rng.Uniform(2.0, 5.0));
      cell_w_ = static_cast<float>(rng.Uniform(4.0, 8.0));
      cell_h_ = static_cast<float>(rng.Uniform(0.9, 1.5));
      joint_m_ = 0.04f;
      cell_variation_ = 0.1f;
      joint_color_ = color_a_ * 0.6f;
      detail_contrast_ = 0.3f;
      detail_scale_m_ = 0.4f;
      detail_octaves_ = 7;
      add_decals(3.0f, 0.5f, 0.7f, kRect | kDisc | kRing, false);  // vents, hatches
      add_decals(1.5f, 0.35f, 0.4f, kBlob, false);
      add_decals(5.0f, 0.3f, 0.9f, kText | kRect, true);
      break;
    case MaterialKind::kMetal: {
      const auto& palette = PaintPalette();
      color_a_ = Jitter(palette[rng.UniformInt(0, 7)] * 0.8f, rng, 0.1f);
      color_b_ = Jitter(color_a_ * 0.85f, rng, 0.1f);
      mix_scale_m_ = 0.6f;
      detail_contrast_ = 0.12f;
      detail_scale_m_ = 0.3f;
      detail_octaves_ = 6;
      add_decals(0.5f, 0.5f, 0.9f, kText | kRect | kStroke, true);
      add_decals(0.3f, 0.4f, 0.5f, kBlob, false);
      break;
    }
    case MaterialKind::kWood:
      color_a_ = Hsv(static_cast<float>(rng.Uniform(0.05, 0.11)),
                     static_cast<float>(rng.Uniform(0.35, 0.6)),
                     static_cast<float>(rng.Uniform(0.25, 0.5)));
      color_b_ = Jitter(color_a_ * 0.75f, rng, 0.15f);
      mix_scale_m_ = 0.8f;
      cell_w_ = static_cast<float>(rng.Uniform(0.9, 2.0));
      cell_h_ = static_cast<float>(rng.Uniform(0.1, 0.2));
      joint_m_ = 0.01f;
      cell_variation_ = 0.25f;
      running_bond_ = static_cast<float>(rng.Uniform(0.2, 0.5));
      joint_color_ = color_a_ * 0.3f;
      detail_contrast_ = 0.3f;
      detail_scale_m_ = 0.25f;
      detail_octaves_ = 6;
      add_decals(0.8f, 0.35f, 0.9f, kText | kRect, true);
      add_decals(0.3f, 0.3f, 0.5f, kDisc | kBlob, false);  // knots
      break;
    case MaterialKind::kContainer: {
      color_a_ = Hsv(static_cast<float>(rng.Uniform()), static_cast<float>(rng.Uniform(0.5, 0.85)),
                     static_cast<float>(rng.Uniform(0.2, 0.5)));
      color_b_ = Jitter(color_a_ * 0.8f, rng, 0.1f);
      mix_scale_m_ = 1.5f;
      stripe_period_m_ = static_cast<float>(rng.Uniform(0.2, 0.35));
      detail_contrast_ = 0.1f;
      detail_scale_m_ = 0.5f;
      detail_octaves_ = 6;
      add_decals(3.0f, 0.7f, 0.95f, kText, true);
      add_decals(1.2f, 0.4f, 0.5f, kBlob | kStroke, false);  // rust
      break;
    }
    case MaterialKind::kBark:
      color_a_ = Hsv(0.08f, 0.4f, static_cast<float>(rng.Uniform(0.08, 0.18)));
      color_b_ = color_a_ * 1.6f;
      mix_scale_m_ = 0.3f;
      detail_contrast_ = 0.3f;
      detail_scale_m_ = 0.25f;
      detail_octaves_ = 6;
      add_decals(0.4f, 0.3f, 0.5f, kBlob, false);
      break;
    case MaterialKind::kFoliage:
      color_a_ =
          Hsv(static_cast<float>(rng.Uniform(0.2, 0.33)), static_cast<float>(rng.Uniform(0.5, 0.8)),
              static_cast<float>(rng.Uniform(0.08, 0.18)));
      color_b_ = Hsv(static_cast<float>(rng.Uniform(0.15, 0.3)), 0.6f,
                     static_cast<float>(rng.Uniform(0.2, 0.35)));
      mix_scale_m_ = 0.35f;
      detail_contrast_ = 0.3f;
      detail_scale_m_ = 0.3f;
      detail_octaves_ = 6;
      add_decals(0.15f, 0.5f, 0.6f, kBlob | kDisc, false);
      break;
  }
}

namespace {

/// Small stones / grains: one random-brightness disc per cell, filtered.
float Speckle(const Vector2d& uv, float fw, float size_m, uint32_t seed) {
  const float weight = Resolved(size_m, fw);
  if (weight <= 0.0f) return 0.0f;
  const double cu = std::floor(uv.x() / size_m);
  const double cv = std::floor(uv.y() / size_m);
  const uint32_t h = HashCell(static_cast<int32_t>(cu), static_cast<int32_t>(cv), seed);
  const uint32_t h2 = Fmix32(h ^ 0x68e31da4u);
  // A grain of random size anywhere in its cell (no visible lattice).
  const float r = size_m * (0.18f + 0.17f * UnitFloat(Fmix32(h)));
  const float room = 0.5f * size_m - r;
  const float du =
      static_cast<float>(uv.x() - (cu + 0.5) * size_m) - room * (2.0f * UnitFloat(h2) - 1.0f);
  const float dv = static_cast<float>(uv.y() - (cv + 0.5) * size_m) -
                   room * (2.0f * UnitFloat(Fmix32(h2 + 0x9e3779b9u)) - 1.0f);
  const float cov = Coverage(std::sqrt(du * du + dv * dv) - r, std::max(fw, 1e-4f));
  return weight * cov * (UnitFloat(h) * 2.0f - 1.0f);
}

/// Brick / tile / plank pattern: returns joint coverage and writes the
/// per-cell brightness offset (already filtered).
float CellPattern(const Vector2d& uv, float fw, float cell_w, float cell_h, float joint, float bond,
                  float variation, uint32_t seed, float* cell_offset) {
  const double row = std::floor(uv.y() / cell_h);
  const double shift = bond * cell_w * (static_cast<int64_t>(row) & 1);
  const double col = std::floor((uv.x() + shift) / cell_w);
  const float du = static_cast<float>(uv.x() + shift - col * cell_w);  // [0, cell_w)
  const float dv = static_cast<float>(uv.y() - row * cell_h);
  const float eu = std::min(du, cell_w - du);  // distance to the vertical joint line
  const float ev = std::min(dv, cell_h - dv);
  const float fwc = std::max(fw, 1e-4f);
  // Joint coverage: resolved lines when joints are wider than the footprint,
  // else their area fraction.
  const float resolved = Resolved(cell_h, fw);
  const float sharp = std::max(Coverage(eu - 0.5f * joint, fwc), Coverage(ev - 0.5f * joint, fwc));
  const float fraction = std::min(1.0f, joint / cell_w + joint / cell_h);
  const float joint_cov = resolved * sharp + (1.0f - resolved) * fraction;
  const uint32_t h = HashCell(static_cast<int32_t>(col), static_cast<int32_t>(row), seed);
  *cell_offset = resolved * variation * (UnitFloat(h) * 2.0f - 1.0f);
  return joint_cov;
}

}  // namespace

void SurfaceTexture::GroundFieldsDirect(const Vector2d& uv, float fields[kGroundFields]) const {
  constexpr float kFw = 1e-3f;  // all wavelengths here are metres: never filtered
  fields[0] = FilteredFbm(uv, kFw, mix_scale_m_, 2, 0.4f, seed_ ^ 0xa1u);
  fields[1] = FilteredFbm(uv, kFw, mix_scale_m_ * 0.8f, 2, 0.4f, seed_ ^ 0xb2u);
  for (int k = 0; k < kNumGroundRegions; ++k) {
    const uint32_t s = seed_ + 0x1000u * static_cast<uint32_t>(k + 1);
    fields[2 + k] =
        Clamp01(0.5f + 0.5f * FilteredFbm(uv, kFw, regions_[static_cast<size_t>(k)].mix_m, 1, 0.55f,
                                          s ^ 0x33u));
  }
}

void SurfaceTexture::GroundFields(const Vector2d& uv, float fields[kGroundFields]) const {
  const LowTable& tab = low_table_;
  const double x = (uv.x() - tab.x0) / tab.step;
  const double y = (uv.y() - tab.y0) / tab.step;
  if (tab.nx < 2 || x < 0.0 || y < 0.0 || x >= tab.nx - 1 || y >= tab.ny - 1) {
    GroundFieldsDirect(uv, fields);
    return;
  }
  const auto ix = static_cast<int>(x), iy = static_cast<int>(y);
  const auto fx = static_cast<float>(x - ix), fy = static_cast<float>(y - iy);
  const float* a = &tab.values[(static_cast<size_t>(iy) * tab.nx + ix) * kGroundFields];
  const float* b = a + static_cast<size_t>(tab.nx) * kGroundFields;
  for (int k = 0; k < kGroundFields; ++k) {
    const float top = a[k] + fx * (a[k + kGroundFields] - a[k]);
    const float bottom = b[k] + fx * (b[k + kGroundFields] - b[k]);
    fields[k] = top + fy * (bottom - top);
  }
}

void SurfaceTexture::PrecomputeGround(double x0, double y0, double x1, double y1, double step) {
  if (kind_ != MaterialKind::kGround) return;
  LowTable tab;
  tab.x0 = x0;
  tab.y0 = y0;
  tab.step = step;
  tab.nx = static_cast<int>(std::ceil((x1 - x0) / step)) + 1;
  tab.ny = static_cast<int>(std::ceil((y1 - y0) / step)) + 1;
  tab.values.resize(static_cast<size_t>(tab.nx) * tab.ny * kGroundFields);
  for (int iy = 0; iy < tab.ny; ++iy) {
    for (int ix = 0; ix < tab.nx; ++ix) {
      GroundFieldsDirect(Vector2d(x0 + ix * step, y0 + iy * step),
                         &tab.values[(static_cast<size_t>(iy) * tab.nx + ix) * kGroundFields]);
    }
  }
  low_table_ = std::move(tab);
}

SurfaceTexture::LowFrequency SurfaceTexture::Low(const Vector2d& uv, float fw) const {
  LowFrequency low;
  if (kind_ != MaterialKind::kGround) {
    const float mix =
        Clamp01(0.5f + 0.5f * FilteredFbm(uv, fw, mix_scale_m_, 2, 0.5f, seed_ ^ 0x11u));
    low.color[0] = Lerp(color_a_, color_b_, mix);
    return low;
  }
  // Region map: two low-frequency fields so all five regions occur with
  // irregular boundaries; the best two regions blend over ~0.4 m. These
  // wavelengths (metres) never need footprint filtering, so they come from
  // a precomputed table where there is one.
  float fields[kGroundFields];
  GroundFields(uv, fields);
  const float r1 = fields[0], r2 = fields[1];
  const float score[kNumGroundRegions] = {r1, -r1, r2, -r2, 0.5f};
  int best = 0, second = 1;
  if (score[1] > score[0]) std::swap(best, second);
  for (int i = 2; i < kNumGroundRegions; ++i) {
    if (score[i] > score[best]) {
      second = best;
      best = i;
    } else if (score[i] > score[second]) {
      second = i;
    }
  }
  constexpr float kBlendWidth = 0.12f;  // in noise units
  const float margin = score[best] - score[second];
  low.region[0] = best;
  low.region[1] = second;
  low.blend = margin >= kBlendWidth ? 1.0f : 0.5f + 0.5f * margin / kBlendWidth;
  for (int k = 0; k < (low.blend < 1.0f ? 2 : 1); ++k) {
    const GroundRegion& r = regions_[static_cast<size_t>(low.region[k])];
    low.color[k] = Lerp(r.a, r.b, fields[2 + low.region[k]]);
  }
  return low;
}

void SurfaceTexture::Detail(const LowFrequency& low, const Vector2d& uv, const Footprint& fp,
                            float brightness[2]) const {
  if (kind_ == MaterialKind::kGround) {
    for (int k = 0; k < (low.blend < 1.0f ? 2 : 1); ++k) {
      const GroundRegion& r = regions_[static_cast<size_t>(low.region[k])];
      const uint32_t s = seed_ + 0x1000u * static_cast<uint32_t>(low.region[k] + 1);
      brightness[k] =
          1.0f + r.detail * FilteredFbm(uv, fp, r.detail_scale_m, r.octaves, 0.7f, s ^ 0x77u);
    }
    return;
  }
  const float stretch =
      (kind_ == MaterialKind::kWood) ? 0.15f : (kind_ == MaterialKind::kBark ? 0.3f : 1.0f);
  brightness[0] = 1.0f + detail_contrast_ * FilteredFbm(uv, fp, detail_scale_m_, detail_octaves_,
                                                        0.6f, seed_ ^ 0x22u, stretch);
}

Vector3f SurfaceTexture::Pattern(const LowFrequency& low, const float brightness_in[2],
                                 const Vector2d& uv, float fw) const {
  if (kind_ == MaterialKind::kGround) {
    Vector3f out = Vector3f::Zero();
    for (int k = 0; k < (low.blend < 1.0f ? 2 : 1); ++k) {
      const GroundRegion& r = regions_[static_cast<size_t>(low.region[k])];
      const uint32_t s = seed_ + 0x1000u * static_cast<uint32_t>(low.region[k] + 1);
      float brightness = brightness_in[k] + r.speckle * Speckle(uv, fw, r.speckle_m, s ^ 0x99u);
      if (r.tile_w > 0.0f) {
        float offset = 0.0f;
        const float joint =
            CellPattern(uv, fw, r.tile_w, r.tile_h, r.joint, 0.5f, 0.2f, s ^ 0x55u, &offset);
        brightness = brightness * (1.0f + offset) * (1.0f - 0.5f * joint);
      }
      out += (k == 0 ? low.blend : 1.0f - low.blend) * low.color[k] * std::max(brightness, 0.05f);
    }
    return out;
  }
  Vector3f c = low.color[0];
  float brightness = brightness_in[0];
  if (cell_w_ > 0.0f) {
    float offset = 0.0f;
    const float joint = CellPattern(uv, fw, cell_w_, cell_h_, joint_m_, running_bond_,
                                    cell_variation_, seed_ ^ 0x44u, &offset);
    c = Lerp(c * (1.0f + offset), joint_color_, joint);
  }
  if (stripe_period_m_ > 0.0f) {
    const float w = Resolved(stripe_period_m_, 2.0f * fw);
    brightness *=
        1.0f + 0.25f * w * static_cast<float>(std::sin(2.0 * M_PI * uv.x() / stripe_period_m_));
  }
  c *= std::max(brightness, 0.05f);
  if (window_w_ > 0.0f && uv.y() > window_sill_) {
    const double iu = std::floor(uv.x() / window_pitch_u_);
    const double iv = std::floor((uv.y() - window_sill_) / window_pitch_v_);
    const float du = static_cast<float>(uv.x() - (iu + 0.5) * window_pitch_u_);
    const float dv =
        static_cast<float>(uv.y() - window_sill_ - iv * window_pitch_v_ - 0.5 * window_h_);
    const float fwc = std::max(fw, 1e-4f);
    const float sd = std::max(std::fabs(du) - 0.5f * window_w_, std::fabs(dv) - 0.5f * window_h_);
    const float cov = Coverage(sd, fwc);
    if (cov > 0.0f) {
      const uint32_t h =
          HashCell(static_cast<int32_t>(iu), static_cast<int32_t>(iv), seed_ ^ 0x66u);
      // Glass: dark, each window its own shade (blinds, reflections).
      Vector3f glass = Vector3f(0.04f, 0.05f, 0.07f) * (1.0f + 4.0f * UnitFloat(h));
      // Frame and mullion: thin light lines.
      const float frame_sd =
          std::min({std::fabs(sd + 0.03f), std::fabs(du), std::fabs(dv)}) - 0.025f;
      const float frame = Coverage(frame_sd, fwc) * Resolved(0.05f, fw);
      glass = Lerp(glass, Vector3f::Constant(0.55f), frame);
      c = Lerp(c, glass, cov);
    }
  }
  return c;
}

Vector3f SurfaceTexture::ApplyDecals(const Vector2d& uv, float fw, Vector3f albedo) const {
  const float fwc = std::max(fw, 1e-4f);
  for (size_t layer_index = 0; layer_index < decals_.size(); ++layer_index) {
    const DecalLayer& layer = decals_[layer_index];
    const double cu = std::floor(uv.x() / layer.cell_m);
    const double cv = std::floor(uv.y() / layer.cell_m);
    uint32_t h = DecalCellHash(static_cast<int32_t>(cu), static_cast<int32_t>(cv),
                               seed_ + 0x632be5abu * static_cast<uint32_t>(layer_index + 1));
    if (UnitFloat(h) >= layer.probability) continue;
    auto next = [&h]() {
      h = Fmix32(h + 0x9e3779b9u);
      return UnitFloat(h);
    };
    const float cell = layer.cell_m;
    const float size = cell * (0.15f + 0.3f * next());  // half extent (m), fits in the cell
    const float cx =
        static_cast<float>(cu * cell) + cell * 0.5f + (next() - 0.5f) * (cell - 2.0f * size);
    const float cy =
        static_cast<float>(cv * cell) + cell * 0.5f + (next() - 0.5f) * (cell - 2.0f * size);
    const float px0 = static_cast<float>(uv.x() - cx);
    const float py0 = static_cast<float>(uv.y() - cy);
    const float reach = 1.4143f * size + fwc;  // any orientation
    if (px0 * px0 + py0 * py0 > reach * reach) continue;
    const uint32_t shape =
        layer.shapes[std::min(static_cast<int>(next() * layer.n_shapes), layer.n_shapes - 1)];
    const auto& dir = DecalDirections()[static_cast<size_t>(next() * 64.0f) & 63u];
    const float ca = dir[0], sa = dir[1];
    const float px = ca * px0 + sa * py0;
    const float py = -sa * px0 + ca * py0;
    if (std::fabs(px) > size + fwc || std::fabs(py) > size + fwc) continue;
    float cov = 0.0f;
    switch (shape) {
      case kDisc:
        cov = Coverage(std::sqrt(px * px + py * py) - size, fwc) * Resolved(size, fw);
        break;
      case kRing: {
        const float width = size * 0.12f;
        cov = Coverage(std::fabs(std::sqrt(px * px + py * py) - size + width) - width, fwc) *
              Resolved(width, fw);
        break;
      }
      case kRect: {
        const float hy = size * (0.3f + 0.7f * next());
        cov = Coverage(std::max(std::fabs(px) - size, std::fabs(py) - hy), fwc) * Resolved(hy, fw);
        break;
      }
      case kStroke: {
        const float width = size * (0.03f + 0.08f * next());
        const float bend = (next() - 0.5f) * 0.6f / size;  // gentle curve
        const float qx = std::max(std::fabs(px) - size, 0.0f);
        const float qy = py - bend * px * px;
        cov = Coverage(std::sqrt(qx * qx + qy * qy) - width, fwc) * Resolved(width, fw);
        break;
      }
      case kBlob: {
        const float r = std::sqrt(px * px + py * py);
        const float wobble =
            0.35f * GradientNoise(px / size * 1.7, py / size * 1.7, h) * kNoiseStdInv * 0.25f;
        cov = Coverage(r - size * (0.75f + wobble), fwc) * Resolved(size, fw);
        break;
      }
      case kText: {
        // A row of glyphs on a 5x7 grid with random cells on: reads like
        // text or a stencil from afar, unique per place.
        const float height = size * (0.25f + 0.25f * next());
        const float c = height / 7.0f;
        const int n_glyphs = std::max(2, static_cast<int>(2.0f * size / (6.0f * c)));
        const float half_len = 0.5f * n_glyphs * 6.0f * c;
        const float box_sd = std::max(std::fabs(px) - half_len, std::fabs(py) - 0.5f * height);
        const float box = Coverage(box_sd, fwc);
        if (box <= 0.0f) break;
        const float density = 0.45f * 5.0f / 6.0f;
        const float resolved = Clamp01(c / fwc - 0.5f);
        float glyph = density;
        if (resolved > 0.0f) {
          // Box filter by four taps at +-fw/4.
          float sum = 0.0f;
          for (int t = 0; t < 4; ++t) {
            const float tx = px + half_len + ((t & 1) ? 0.25f : -0.25f) * fwc;
            const float ty = py + 0.5f * height + ((t & 2) ? 0.25f : -0.25f) * fwc;
            if (tx < 0.0f || ty < 0.0f || ty >= height || tx >= 2.0f * half_len) continue;
            const int gi = static_cast<int>(tx / (6.0f * c));
            const int col = static_cast<int>((tx - gi * 6.0f * c) / c);
            const int row = static_cast<int>(ty / c);
            if (col >= 5) continue;
            sum += UnitFloat(HashCell(gi, row * 5 + col, h)) < 0.45f ? 1.0f : 0.0f;
          }
          glyph = resolved * 0.25f * sum + (1.0f - resolved) * density;
        }
        cov = box * glyph * Resolved(height, fw);
        break;
      }
      default:
        break;
    }
    if (cov <= 0.0f) continue;
    Vector3f target;
    if (layer.paint) {
      target = PaintPalette()[static_cast<size_t>(next() * 8.0f) & 7u];
    } else {
      const float dark = next() < 0.7f ? 0.35f + 0.3f * next() : 1.5f + 0.5f * next();
      target = (albedo * dark).cwiseMin(0.9f);
    }
    albedo = Lerp(albedo, target, cov * layer.contrast);
  }
  return albedo;
}

Vector3f SurfaceTexture::Albedo(const Vector2d& uv, double footprint_m, const Vector2d& major_uv,
                                int taps, const TextureImages* images) const {
  // Anisotropic footprint: `taps` samples along the long axis, each filtered
  // to its share of it; slowly varying content is evaluated once.
  Footprint fp;
  fp.minor = static_cast<float>(std::max(footprint_m, 1e-5));
  fp.major = major_uv;
  fp.major_len = std::max(static_cast<float>(major_uv.norm()), fp.minor);
  fp.taps = fp.major_len > fp.minor ? std::max(taps, 1) : 1;
  const float fw_tap = std::max(fp.minor, fp.major_len / static_cast<float>(fp.taps));
  const bool use_images = images != nullptr && !images->empty();
  LowFrequency low;
  float brightness[2] = {1.0f, 1.0f};
  float modulation = 1.0f;
  Vector2d image_offset = Vector2d::Zero();
  if (use_images) {
    // A random offset per surface so surfaces sharing an image differ, and a
    // low-frequency brightness modulation against visible tiling.
    image_offset = Vector2d(static_cast<double>(image_pick_ % 1000) * 0.37,
                            static_cast<double>((image_pick_ / 1000) % 1000) * 0.53);
    modulation = 1.0f + 0.25f * FilteredFbm(uv, fp.major_len, 6.0f, 3, 0.5f, seed_ ^ 0x88u);
  } else {
    low = Low(uv, fp.major_len);
    Detail(low, uv, fp, brightness);
  }
  Vector3f sum = Vector3f::Zero();
  for (int k = 0; k < fp.taps; ++k) {
    const Vector2d p = fp.taps == 1 ? uv : Vector2d(uv + ((k + 0.5) / fp.taps - 0.5) * major_uv);
    const Vector3f c =
        use_images ? Vector3f(modulation * images->Sample(static_cast<size_t>(image_pick_ >> 24),
                                                          p + image_offset, fw_tap))
                   : Pattern(low, brightness, p, fw_tap);
    // Each tap looks up its own decal cells: cheaper than first finding the
    // layers with a decal anywhere under the footprint, and the same result
    // (a layer without a decal in a tap's cell leaves that tap unchanged).
    sum += ApplyDecals(p, fw_tap, c);
  }
  return (sum / static_cast<float>(fp.taps)).cwiseMax(0.0f).cwiseMin(1.0f);
}

}  // namespace ag
