#pragma once

// The simulated world: an infinite textured ground plane (z = 0) plus boxes
// (buildings, walls, crates, containers), vertical cylinders (poles, trunks,
// barrels) and spheres (tree canopies), in the scene frame W (z up). Rays are
// cast exactly against this geometry through a uniform 2-D grid.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "tools/sim/texture.h"

namespace ag {

/// Options of the procedural world (scenario key `world`).
struct WorldOptions {
  double size_x_m = 60.0;   ///< extent of the populated area along x, centred on center_x_m (m)
  double size_y_m = 60.0;   ///< extent along y (m)
  double center_x_m = 0.0;  ///< centre of the populated area (m)
  double center_y_m = 0.0;
  int buildings = 6;                 ///< number of buildings
  double building_min_size_m = 6.0;  ///< footprint edge range (m)
  double building_max_size_m = 14.0;
  double building_min_height_m = 3.0;  ///< height range (m)
  double building_max_height_m = 9.0;
  int walls = 8;             ///< free-standing walls and fences
  int poles = 20;            ///< lamp posts, sign posts
  int trees = 12;            ///< trunk + canopy
  int clutter = 40;          ///< crates, containers, barrels, blocks
  bool perimeter = true;     ///< a ring of buildings and trees just outside the area (horizon)
  double clearance_m = 1.5;  ///< free space kept around the agents' paths (m)
  double sun_azimuth_deg = 140.0;   ///< direction of the sun, from +x towards +y (deg)
  double sun_elevation_deg = 50.0;  ///< above the horizon (deg)
  bool shadows = true;              ///< cast sun shadows
  double ambient = 0.45;            ///< sky light relative to direct sun
  double texture_texel_m = 0.01;    ///< metres per texel of --textures images (m)

  template <class V>
  void VisitFields(V& v) {
    v("size_x_m", size_x_m);
    v("size_y_m", size_y_m);
    v("center_x_m", center_x_m);
    v("center_y_m", center_y_m);
    v("buildings", buildings);
    v("building_min_size_m", building_min_size_m);
    v("building_max_size_m", building_max_size_m);
    v("building_min_height_m", building_min_height_m);
    v("building_max_height_m", building_max_height_m);
    v("walls", walls);
    v("poles", poles);
    v("trees", trees);
    v("clutter", clutter);
    v("perimeter", perimeter);
    v("clearance_m", clearance_m);
    v("sun_azimuth_deg", sun_azimuth_deg);
    v("sun_elevation_deg", sun_elevation_deg);
    v("shadows", shadows);
    v("ambient", ambient);
    v("texture_texel_m", texture_texel_m);
  }
  void Check() const;
};

/// One solid of the world.
struct SimObject {
  enum class Shape : uint8_t { kBox, kCylinder, kSphere };
  Shape shape = Shape::kBox;
  /// Box: centre; cylinder: centre of the axis; sphere: centre (m, frame W).
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  /// Box: half extents along its local x y z; cylinder: (radius, radius,
  /// half height); sphere: (radius, radius, radius) (m).
  Eigen::Vector3d half = Eigen::Vector3d::Ones();
  double yaw = 0.0;                     ///< box rotation about z (rad)
  double cos_yaw = 1.0, sin_yaw = 0.0;  ///< of yaw, set by SimWorld::AddObject
  /// Surfaces (indices into SimWorld::surfaces): box: 4 sides then top;
  /// cylinder: side then top; sphere: one.
  int first_surface = 0;
};

/// Where a ray met the world.
struct RayHit {
  double t = 0.0;                                ///< ray parameter (m along a unit direction)
  int object = -1;                               ///< index into objects(); -1 = ground plane
  int surface = 0;                               ///< texture index
  Eigen::Vector3d p = Eigen::Vector3d::Zero();   ///< hit point (W)
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  ///< outward unit normal (W)
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  ///< surface coordinates (m)
  Eigen::Vector3d tangent_u = Eigen::Vector3d::UnitX();  ///< world direction of increasing u
  Eigen::Vector3d tangent_v = Eigen::Vector3d::UnitY();  ///< world direction of increasing v
};

/// A path the world must keep clear: objects whose top is above `below_z`
/// stay `radius_m` (plus their own size) away from every polyline point.
struct KeepOutPath {
  std::vector<Eigen::Vector2d> points;  ///< densely sampled path (m, W)
  double radius_m = 1.5;
  double below_z = -1e9;  ///< objects lower than this may stand on the path (m)
};

class SimWorld {
 public:
  /// An empty world (ground plane only); add objects with AddObject.
  explicit SimWorld(uint64_t seed, WorldOptions options = {});

  /// Generates the procedural world of `options` for `seed`, keeping the
  /// given paths clear.
  static SimWorld Generate(const WorldOptions& options, uint64_t seed,
                           const std::vector<KeepOutPath>& keep_out);

  /// Adds a solid with fresh surfaces of the given materials (box: sides,
  /// top; cylinder: side, top; sphere: side). Invalidates nothing; call
  /// BuildIndex() before casting.
  int AddObject(SimObject object, MaterialKind side, MaterialKind top);

  /// (Re)builds the ray-casting grid. Generate() calls it.
  void BuildIndex();

  /// First hit of the ray origin + t * dir (dir unit) with t in (t_min,
  /// t_max). Returns false when nothing is hit (sky).
  bool Cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_max, RayHit* hit,
            double t_min = 1e-6) const;

  /// True when anything blocks the segment origin + t * dir, t in (t_min, t_max).
  bool Occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_max,
                double t_min = 1e-6) const;

  /// Linear albedo at a hit, prefiltered to a footprint `footprint_m` wide
  /// and `major_uv` long (surface vector, m) covered by `taps` samples.
  Eigen::Vector3f Albedo(const RayHit& hit, double footprint_m,
                         const Eigen::Vector2d& major_uv = Eigen::Vector2d::Zero(),
                         int taps = 1) const;

  /// Irradiance factor (ambient + sun) at a hit, with the sun shadow.
  float Irradiance(const RayHit& hit, bool* in_shadow = nullptr) const;

  /// Sky radiance seen along a direction.
  Eigen::Vector3f Sky(const Eigen::Vector3d& dir) const;

  /// Uses images from a folder instead of procedural albedo (not owned).
  void SetTextureImages(const TextureImages* images) { images_ = images; }

  const std::vector<SimObject>& objects() const { return objects_; }
  const WorldOptions& options() const { return options_; }
  const Eigen::Vector3d& sun_direction() const { return sun_; }
  double max_object_z() const { return max_z_; }

 private:
  /// Ray parameter of the first hit with object `index` in (t_min, t_max),
  /// or infinity; `face` says which face (FillHit turns it into a RayHit).
  double IntersectObject(int index, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                         double t_min, double t_max, int* face) const;
  void FillHit(int index, int face, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t,
               RayHit* hit) const;
  /// Fills the sun index from the objects' xy bounding boxes.
  void BuildSunIndex(const std::vector<Eigen::Vector4d>& boxes);
  /// True when no object can block the sun from p (p.z >= 0), so the
  /// shadow ray need not be cast; false when unsure.
  bool SunSurelyVisible(const Eigen::Vector3d& p) const;
  template <bool kAnyHit>
  bool Traverse(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min, double t_max,
                RayHit* hit) const;

  WorldOptions options_;
  uint64_t seed_ = 0;
  std::vector<SimObject> objects_;
  std::vector<SurfaceTexture> surfaces_;  ///< 0 = ground
  const TextureImages* images_ = nullptr;
  Eigen::Vector3d sun_ = Eigen::Vector3d::UnitZ();
  // Uniform grid over the objects' xy bounds.
  double grid_x0_ = 0.0, grid_y0_ = 0.0, cell_m_ = 2.0;
  double inv_cell_m_ = 0.5;   ///< 1 / cell_m_
  bool cell_is_pow2_ = true;  ///< cell_m_ is a power of two: dividing = multiplying by inv_cell_m_
  int grid_nx_ = 0, grid_ny_ = 0;
  std::vector<uint32_t> cell_start_;  ///< CSR offsets, size nx*ny+1
  std::vector<uint32_t> cell_items_;
  std::vector<double> cell_top_;  ///< highest object top per cell (m)
  double max_z_ = 0.0;            ///< top of the tallest object (m)
  // Sun index: a grid over xy marking where some object may shadow a point.
  double sun_x0_ = 0.0, sun_y0_ = 0.0, sun_cell_m_ = 0.5;
  int sun_nx_ = 0, sun_ny_ = 0;
  std::vector<uint8_t> sun_blockable_;
};

}  // namespace ag
