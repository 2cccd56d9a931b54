#pragma once

#include <array>

// Surface textures of the simulated world, defined in world units: a texture
// is a function of the 2-D surface coordinates (metres) of a point, so the
// same point looks the same from the air (metres away, oblique) and from the
// ground (decimetres away). Every evaluation is prefiltered by the pixel
// footprint (metres): detail finer than the footprint fades to its mean, the
// procedural equivalent of mip-mapping, so far views do not alias.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace ag {

/// What a surface is made of; selects the procedural recipe.
enum class MaterialKind : uint8_t {
  kGround,     ///< the ground plane: asphalt / grass / gravel / pavers / dirt regions
  kBrick,      ///< brick facade with windows
  kPlaster,    ///< rendered facade with windows
  kConcrete,   ///< concrete wall with stains, tags and text
  kRoof,       ///< flat roof: gravel / membrane with seams and vents
  kMetal,      ///< painted metal (poles, signs)
  kWood,       ///< planks (crates, fences)
  kContainer,  ///< corrugated metal with large stencilled text
  kBark,       ///< tree trunks
  kFoliage,    ///< tree canopies
};

/// Images for `--textures DIR`: each surface picks one image (seeded) and
/// maps it at `texel_m` metres per texel, sampled trilinearly from a mip
/// pyramid chosen by the footprint.
class TextureImages {
 public:
  /// Loads every .png/.jpg/.jpeg/.bmp/.tif file of `dir` in sorted name
  /// order. Throws ag::InputError when the folder is missing, holds no
  /// image or an image cannot be decoded.
  static TextureImages LoadFolder(const std::string& dir, double texel_m);

  bool empty() const { return images_.empty(); }
  size_t size() const { return images_.size(); }

  /// Linear RGB albedo of image `index` at surface coordinates uv (m),
  /// prefiltered to `footprint_m`.
  Eigen::Vector3f Sample(size_t index, const Eigen::Vector2d& uv, double footprint_m) const;

 private:
  struct Level {
    int width = 0, height = 0;
    std::vector<Eigen::Vector3f> texels;  ///< row-major, linear RGB
  };
  std::vector<std::vector<Level>> images_;  ///< per image, level 0 = full size
  double texel_m_ = 0.01;
};

/// One surface's texture: a material recipe with parameters drawn from the
/// surface's seed, so no two surfaces look alike.
class SurfaceTexture {
 public:
  /// A pixel's footprint on the surface: `minor` wide (m) and `major` long
  /// (surface vector, m), sampled by `taps` along the long axis.
  struct Footprint {
    float minor = 1e-3f;
    Eigen::Vector2d major = Eigen::Vector2d::Zero();
    float major_len = 1e-3f;  ///< |major|, >= minor
    int taps = 1;
  };

  SurfaceTexture() = default;
  SurfaceTexture(MaterialKind kind, uint64_t seed);

  /// Linear RGB albedo (0..1) at surface coordinates uv (m), prefiltered to
  /// the footprint: `footprint_m` across, and `major_uv` (surface vector,
  /// m) along its long axis, covered by `taps` samples (anisotropic
  /// filtering). `images` may be null.
  Eigen::Vector3f Albedo(const Eigen::Vector2d& uv, double footprint_m,
                         const Eigen::Vector2d& major_uv = Eigen::Vector2d::Zero(), int taps = 1,
                         const TextureImages* images = nullptr) const;

  MaterialKind kind() const { return kind_; }

  /// Ground only: tabulates the slowly varying fields (region map, colour
  /// mixing) over a rectangle (m) every `step` m; lookups interpolate
  /// bilinearly, outside it they are evaluated directly.
  void PrecomputeGround(double x0, double y0, double x1, double y1, double step);

 private:
  struct DecalLayer {
    float cell_m = 1.0f;       ///< grid cell holding at most one decal (m)
    float probability = 0.0f;  ///< chance a cell holds a decal
    float contrast = 0.5f;     ///< how far the decal pulls the albedo
    uint32_t shapes[6] = {};   ///< DecalShape values allowed
    int n_shapes = 0;
    bool paint = false;  ///< bright paint colours instead of stains
  };

  /// One region type of the ground (asphalt, grass, gravel, pavers, dirt).
  struct GroundRegion {
    Eigen::Vector3f a{0.2f, 0.2f, 0.2f}, b{0.2f, 0.2f, 0.2f};  ///< colours mixed at mix_m
    float mix_m = 3.0f;                                        ///< colour-mixing scale (m)
    float detail = 0.3f;                                       ///< fine-noise contrast
    float detail_scale_m = 0.3f;  ///< largest fine-noise wavelength (m)
    int octaves = 6;
    float tile_w = 0.0f, tile_h = 0.0f, joint = 0.0f;  ///< pavers (m); tile_w 0 = none
    float speckle = 0.0f;                              ///< grain / stone contrast
    float speckle_m = 0.01f;                           ///< grain size (m)
  };

  static GroundRegion MakeGroundRegion(int type, uint64_t seed);
  /// What varies slowly (colour mixing, ground regions): evaluated once per
  /// footprint.
  struct LowFrequency {
    std::array<Eigen::Vector3f, 2> color;
    int region[2] = {0, 0};  ///< ground: the two nearest regions
    float blend = 1.0f;      ///< ground: weight of region[0]
  };
  LowFrequency Low(const Eigen::Vector2d& uv, float fw) const;
  static constexpr int kGroundFields = 7;  ///< two region fields, five colour mixes
  void GroundFieldsDirect(const Eigen::Vector2d& uv, float fields[kGroundFields]) const;
  void GroundFields(const Eigen::Vector2d& uv, float fields[kGroundFields]) const;
  struct LowTable {
    double x0 = 0.0, y0 = 0.0, step = 1.0;
    int nx = 0, ny = 0;
    std::vector<float> values;  ///< kGroundFields per node, row-major
  };
  /// Relative brightness of the fine noise (per blended region), filtered
  /// over the whole (anisotropic) footprint.
  void Detail(const LowFrequency& low, const Eigen::Vector2d& uv, const Footprint& fp,
              float brightness[2]) const;
  /// Patterns, windows and grains at one tap of the footprint.
  Eigen::Vector3f Pattern(const LowFrequency& low, const float brightness[2],
                          const Eigen::Vector2d& uv, float fw) const;
  /// The decals covering uv (each layer has at most one per grid cell, so
  /// only the cell holding uv is looked at).
  Eigen::Vector3f ApplyDecals(const Eigen::Vector2d& uv, float fw, Eigen::Vector3f albedo) const;

  MaterialKind kind_ = MaterialKind::kConcrete;
  uint32_t seed_ = 0;
  uint64_t image_pick_ = 0;
  Eigen::Vector3f color_a_{0.3f, 0.3f, 0.3f};
  Eigen::Vector3f color_b_{0.3f, 0.3f, 0.3f};
  float mix_scale_m_ = 4.0f;      ///< scale of the colour-mixing noise (m)
  float detail_contrast_ = 0.3f;  ///< relative amplitude of fine noise
  float detail_scale_m_ = 1.0f;   ///< largest wavelength of the fine noise (m)
  int detail_octaves_ = 8;        ///< octaves below detail_scale_m_
  float cell_w_ = 0.0f;           ///< brick / tile / plank width (m); 0 = no pattern
  float cell_h_ = 0.0f;           ///< brick / tile / plank height (m)
  float joint_m_ = 0.0f;          ///< joint / mortar width (m)
  float cell_variation_ = 0.0f;   ///< per-cell brightness variation (relative)
  float running_bond_ = 0.0f;     ///< row offset as a fraction of cell width
  Eigen::Vector3f joint_color_{0.2f, 0.2f, 0.2f};
  float window_w_ = 0.0f;  ///< window width (m); 0 = no windows
  float window_h_ = 0.0f;
  float window_pitch_u_ = 0.0f;  ///< window spacing (m)
  float window_pitch_v_ = 0.0f;
  float window_sill_ = 0.0f;      ///< height of the first row of windows (m)
  float stripe_period_m_ = 0.0f;  ///< corrugation period (m); 0 = none
  std::vector<DecalLayer> decals_;
  std::vector<GroundRegion> regions_;  ///< kGround only
  LowTable low_table_;                 ///< kGround only
};

}  // namespace ag
