#include "tools/sim/world.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "tools/sim/random.h"

namespace ag {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kDeg = M_PI / 180.0;

/// A footprint already taken by an object (bounding circle).
struct Footprint {
  Vector2d center;
  double radius;
};

}  // namespace

void WorldOptions::Check() const {
  CheckOption(size_x_m >= 10.0 && size_y_m >= 10.0, "size_x_m",
              "area must be at least 10 m x 10 m");
  CheckOption(buildings >= 0 && walls >= 0 && poles >= 0 && trees >= 0 && clutter >= 0, "buildings",
              "object counts must be >= 0");
  CheckOption(building_min_size_m > 0 && building_max_size_m >= building_min_size_m,
              "building_max_size_m", "must be >= building_min_size_m > 0");
  CheckOption(building_min_height_m > 0 && building_max_height_m >= building_min_height_m,
              "building_max_height_m", "must be >= building_min_height_m > 0");
  CheckOption(clearance_m >= 0, "clearance_m", "must be >= 0");
  CheckOption(sun_elevation_deg > 0 && sun_elevation_deg <= 90, "sun_elevation_deg",
              "must be in (0, 90]");
  CheckOption(ambient >= 0 && ambient <= 2, "ambient", "must be in [0, 2]");
  CheckOption(texture_texel_m > 0, "texture_texel_m", "must be > 0");
}

SimWorld::SimWorld(uint64_t seed, WorldOptions options) : options_(options), seed_(seed) {
  surfaces_.emplace_back(MaterialKind::kGround, HashCombine(seed_, HashString("ground")));
  const double az = options_.sun_azimuth_deg * kDeg;
  const double el = options_.sun_elevation_deg * kDeg;
  sun_ = Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
}

int SimWorld::AddObject(SimObject object, MaterialKind side, MaterialKind top) {
  object.first_surface = static_cast<int>(surfaces_.size());
  object.cos_yaw = std::cos(object.yaw);
  object.sin_yaw = std::sin(object.yaw);
  auto add_surface = [&](MaterialKind kind) {
    surfaces_.emplace_back(kind, HashCombine(seed_, surfaces_.size() * 7919 + 17));
  };
  switch (object.shape) {
    case SimObject::Shape::kBox:
      for (int i = 0; i < 4; ++i) add_surface(side);
      add_surface(top);
      break;
    case SimObject::Shape::kCylinder:
      add_surface(side);
      add_surface(top);
      break;
    case SimObject::Shape::kSphere:
      add_surface(side);
      break;
  }
  objects_.push_back(object);
  return static_cast<int>(objects_.size()) - 1;
}

void SimWorld::BuildIndex() {
  cell_start_.clear();
  cell_items_.clear();
  grid_nx_ = grid_ny_ = 0;
  sun_nx_ = sun_ny_ = 0;
  max_z_ = 0.0;
  if (objects_.empty()) return;
  std::vector<Eigen::Vector4d> boxes;  // xmin ymin xmax ymax
  double x0 = kInf, y0 = kInf, x1 = -kInf, y1 = -kInf;
  for (const SimObject& o : objects_) {
    double ex = o.half.x(), ey = o.half.y();
    if (o.shape == SimObject::Shape::kBox) {
      const double c = std::fabs(std::cos(o.yaw)), s = std::fabs(std::sin(o.yaw));
      ex = c * o.half.x() + s * o.half.y();
      ey = s * o.half.x() + c * o.half.y();
    }
    const Eigen::Vector4d b(o.center.x() - ex, o.center.y() - ey, o.center.x() + ex,
                            o.center.y() + ey);
    boxes.push_back(b);
    x0 = std::min(x0, b[0]);
    y0 = std::min(y0, b[1]);
    x1 = std::max(x1, b[2]);
    y1 = std::max(y1, b[3]);
    max_z_ = std::max(max_z_, o.center.z() + o.half.z());
  }
  cell_m_ = std::max(2.0, std::max(x1 - x0, y1 - y0) / 2048.0);
  inv_cell_m_ = 1.0 / cell_m_;
  // A power of two (the usual 2 m) has an exact reciprocal.
  cell_is_pow2_ = std::scalbn(1.0, std::ilogb(cell_m_)) == cell_m_;
  grid_x0_ = x0 - 0.5;
  grid_y0_ = y0 - 0.5;
  grid_nx_ = static_cast<int>(std::ceil((x1 + 0.5 - grid_x0_) / cell_m_));
  grid_ny_ = static_cast<int>(std::ceil((y1 + 0.5 - grid_y0_) / cell_m_));
  auto cell_range = [&](const Eigen::Vector4d& b, int* ix0, int* iy0, int* ix1, int* iy1) {
    *ix0 = std::clamp(static_cast<int>(std::floor((b[0] - grid_x0_) / cell_m_)), 0, grid_nx_ - 1);
    *iy0 = std::clamp(static_cast<int>(std::floor((b[1] - grid_y0_) / cell_m_)), 0, grid_ny_ - 1);
    *ix1 = std::clamp(static_cast<int>(std::floor((b[2] - grid_x0_) / cell_m_)), 0, grid_nx_ - 1);
    *iy1 = std::clamp(static_cast<int>(std::floor((b[3] - grid_y0_) / cell_m_)), 0, grid_ny_ - 1);
  };
  std::vector<uint32_t> counts(static_cast<size_t>(grid_nx_) * grid_ny_ + 1, 0);
  for (const auto& b : boxes) {
    int ix0, iy0, ix1, iy1;
    cell_range(b, &ix0, &iy0, &ix1, &iy1);
    for (int iy = iy0; iy <= iy1; ++iy)
      for (int ix = ix0; ix <= ix1; ++ix) ++counts[static_cast<size_t>(iy) * grid_nx_ + ix + 1];
  }
  for (size_t i = 1; i < counts.size(); ++i) counts[i] += counts[i - 1];
  cell_start_ = counts;
  cell_items_.resize(counts.back());
  std::vector<uint32_t> fill(counts.begin(), counts.end() - 1);
  BuildSunIndex(boxes);
  cell_top_.assign(static_cast<size_t>(grid_nx_) * grid_ny_, -kInf);
  for (size_t k = 0; k < boxes.size(); ++k) {
    int ix0, iy0, ix1, iy1;
    cell_range(boxes[k], &ix0, &iy0, &ix1, &iy1);
    const double top = objects_[k].center.z() + objects_[k].half.z();
    for (int iy = iy0; iy <= iy1; ++iy) {
      for (int ix = ix0; ix <= ix1; ++ix) {
        const size_t cell = static_cast<size_t>(iy) * grid_nx_ + ix;
        cell_items_[fill[cell]++] = static_cast<uint32_t>(k);
        cell_top_[cell] = std::max(cell_top_[cell], top);
      }
    }
  }
}

void SimWorld::BuildSunIndex(const std::vector<Eigen::Vector4d>& boxes) {
  // A sun ray from a point at height >= 0 meets an object only if the point
  // lies under the object's bounding box swept away from the sun down to
  // the ground: the box's footprint stretched by top / tan(elevation)
  // against the sun's azimuth. Cells outside every such region see the sun.
  std::vector<Eigen::Vector4d> regions;  // xmin ymin xmax ymax
  double x0 = kInf, y0 = kInf, x1 = -kInf, y1 = -kInf;
  for (size_t k = 0; k < boxes.size(); ++k) {
    const double top = objects_[k].center.z() + objects_[k].half.z();
    const double reach = std::max(top, 0.0) / sun_.z();
    const double ex = -sun_.x() * reach, ey = -sun_.y() * reach;
    // The margin dwarfs any rounding in the ray-object tests.
    constexpr double kMargin = 0.05;
    const Eigen::Vector4d r(
        boxes[k][0] + std::min(ex, 0.0) - kMargin, boxes[k][1] + std::min(ey, 0.0) - kMargin,
        boxes[k][2] + std::max(ex, 0.0) + kMargin, boxes[k][3] + std::max(ey, 0.0) + kMargin);
    regions.push_back(r);
    x0 = std::min(x0, r[0]);
    y0 = std::min(y0, r[1]);
    x1 = std::max(x1, r[2]);
    y1 = std::max(y1, r[3]);
  }
  sun_cell_m_ = std::max(0.5, std::max(x1 - x0, y1 - y0) / 2048.0);
  sun_x0_ = x0;
  sun_y0_ = y0;
  sun_nx_ = static_cast<int>(std::ceil((x1 - x0) / sun_cell_m_)) + 1;
  sun_ny_ = static_cast<int>(std::ceil((y1 - y0) / sun_cell_m_)) + 1;
  sun_blockable_.assign(static_cast<size_t>(sun_nx_) * sun_ny_, 0);
  for (const Eigen::Vector4d& r : regions) {
    const int ix0 = static_cast<int>(std::floor((r[0] - sun_x0_) / sun_cell_m_));
    const int iy0 = static_cast<int>(std::floor((r[1] - sun_y0_) / sun_cell_m_));
    const int ix1 =
        std::min(static_cast<int>(std::floor((r[2] - sun_x0_) / sun_cell_m_)), sun_nx_ - 1);
    const int iy1 =
        std::min(static_cast<int>(std::floor((r[3] - sun_y0_) / sun_cell_m_)), sun_ny_ - 1);
    for (int iy = std::max(iy0, 0); iy <= iy1; ++iy) {
      for (int ix = std::max(ix0, 0); ix <= ix1; ++ix)
        sun_blockable_[static_cast<size_t>(iy) * sun_nx_ + ix] = 1;
    }
  }
}

bool SimWorld::SunSurelyVisible(const Vector3d& p) const {
  if (sun_nx_ == 0 || !(p.z() >= 0.0)) return false;
  const double fx = std::floor((p.x() - sun_x0_) / sun_cell_m_);
  const double fy = std::floor((p.y() - sun_y0_) / sun_cell_m_);
  if (fx < 0.0 || fy < 0.0 || fx >= sun_nx_ || fy >= sun_ny_) return true;  // outside every region
  return !sun_blockable_[static_cast<size_t>(fy) * sun_nx_ + static_cast<size_t>(fx)];
}

double SimWorld::IntersectObject(int index, const Vector3d& o, const Vector3d& d, double t_min,
                                 double t_max, int* face) const {
  const SimObject& obj = objects_[static_cast<size_t>(index)];
  switch (obj.shape) {
    case SimObject::Shape::kBox: {
      const double c = obj.cos_yaw, s = obj.sin_yaw;
      const Vector3d q0 = o - obj.center;
      const double ql[3] = {c * q0.x() + s * q0.y(), -s * q0.x() + c * q0.y(), q0.z()};
      const double dl[3] = {c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z()};
      double t_near = -kInf, t_far = kInf;
      int near_face = -1;
      for (int i = 0; i < 3; ++i) {
        const double h = obj.half[i];
        if (std::fabs(dl[i]) < 1e-15) {
          if (std::fabs(ql[i]) > h) return kInf;
          continue;
        }
        const double inv = 1.0 / dl[i];
        double ta = (-h - ql[i]) * inv, tb = (h - ql[i]) * inv;
        if (ta > tb) std::swap(ta, tb);
        if (ta > t_near) {
          t_near = ta;
          near_face = 2 * i + (dl[i] > 0 ? 1 : 0);  // entering through the -h face when moving +
        }
        t_far = std::min(t_far, tb);
        if (t_near > t_far) return kInf;
      }
      if (near_face < 0 || t_near <= t_min || t_near >= t_max) return kInf;
      *face = near_face;
      return t_near;
    }
    case SimObject::Shape::kCylinder: {
      const double r = obj.half.x();
      const double z0 = obj.center.z() - obj.half.z(), z1 = obj.center.z() + obj.half.z();
      const double qx = o.x() - obj.center.x(), qy = o.y() - obj.center.y();
      double best = t_max;
      int best_face = -1;
      const double a = d.x() * d.x() + d.y() * d.y();
      if (a > 1e-18) {
        const double b = qx * d.x() + qy * d.y();
        const double cc = qx * qx + qy * qy - r * r;
        const double disc = b * b - a * cc;
        if (disc < 0.0) return kInf;  // the infinite cylinder is missed, so are the caps
        const double t = (-b - std::sqrt(disc)) / a;
        const double z = o.z() + t * d.z();
        if (t > t_min && t < best && z >= z0 && z <= z1) {
          best = t;
          best_face = 0;
        }
      }
      if (std::fabs(d.z()) > 1e-15) {
        // A cap is entered from outside only: the top from above, the bottom from below.
        const double zc = d.z() < 0 ? z1 : z0;
        const double t = (zc - o.z()) / d.z();
        if (t > t_min && t < best) {
          const double x = qx + t * d.x(), y = qy + t * d.y();
          if (x * x + y * y <= r * r) {
            best = t;
            best_face = d.z() < 0 ? 1 : 2;
          }
        }
      }
      if (best_face < 0) return kInf;
      *face = best_face;
      return best;
    }
    case SimObject::Shape::kSphere: {
      const double r = obj.half.x();
      const Vector3d q = o - obj.center;
      const double b = q.dot(d);
      const double cc = q.squaredNorm() - r * r;
      const double disc = b * b - cc;
      if (disc < 0.0) return kInf;
      const double t = -b - std::sqrt(disc);
      if (t <= t_min || t >= t_max) return kInf;
      *face = 0;
      return t;
    }
  }
  return kInf;
}

void SimWorld::FillHit(int index, int face, const Vector3d& o, const Vector3d& d, double t,
                       RayHit* hit) const {
  const SimObject& obj = objects_[static_cast<size_t>(index)];
  hit->t = t;
  hit->object = index;
  hit->p = o + t * d;
  switch (obj.shape) {
    case SimObject::Shape::kBox: {
      const double c = obj.cos_yaw, s = obj.sin_yaw;
      auto to_world = [&](const Vector3d& v) {
        return Vector3d(c * v.x() - s * v.y(), s * v.x() + c * v.y(), v.z());
      };
      const Vector3d q0 = hit->p - obj.center;
      const Vector3d pl(c * q0.x() + s * q0.y(), -s * q0.x() + c * q0.y(), q0.z());
      const int axis = face / 2;
      const double sign = (face % 2 == 0) ? 1.0 : -1.0;
      Vector3d nl = Vector3d::Zero();
      nl[axis] = sign;
      hit->n = to_world(nl);
      if (axis == 2) {
        hit->surface = obj.first_surface + 4;
        hit->uv = Vector2d(pl.x(), pl.y());
        hit->tangent_u = to_world(Vector3d::UnitX());
        hit->tangent_v = to_world(Vector3d::UnitY());
      } else {
        // Sides: u runs along the face (counter-clockwise seen from above), v
        // is the height above the ground so facade rows line up with floors.
        const Vector3d tu = axis == 0 ? Vector3d(0, sign, 0) : Vector3d(-sign, 0, 0);
        hit->surface = obj.first_surface + face;
        hit->uv = Vector2d(tu.dot(pl), hit->p.z());
        hit->tangent_u = to_world(tu);
        hit->tangent_v = Vector3d::UnitZ();
      }
      return;
    }
    case SimObject::Shape::kCylinder: {
      const double r = obj.half.x();
      const double x = hit->p.x() - obj.center.x(), y = hit->p.y() - obj.center.y();
      if (face == 0) {
        const double phi = std::atan2(y, x);
        hit->n = Vector3d(x / r, y / r, 0.0);
        hit->surface = obj.first_surface;
        hit->uv = Vector2d(r * phi, hit->p.z());
        hit->tangent_u = Vector3d(-y / r, x / r, 0.0);
        hit->tangent_v = Vector3d::UnitZ();
      } else {
        hit->n = Vector3d(0, 0, face == 1 ? 1.0 : -1.0);
        hit->surface = obj.first_surface + 1;
        hit->uv = Vector2d(x, y);
        hit->tangent_u = Vector3d::UnitX();
        hit->tangent_v = Vector3d::UnitY();
      }
      return;
    }
    case SimObject::Shape::kSphere: {
      const double r = obj.half.x();
      hit->n = (hit->p - obj.center) / r;
      const double az = std::atan2(hit->n.y(), hit->n.x());
      const double el = std::asin(std::clamp(hit->n.z(), -1.0, 1.0));
      const double horizontal = std::hypot(hit->n.x(), hit->n.y());
      const double ca = horizontal > 1e-12 ? hit->n.x() / horizontal : 1.0;
      const double sa = horizontal > 1e-12 ? hit->n.y() / horizontal : 0.0;
      hit->surface = obj.first_surface;
      hit->uv = Vector2d(r * az * horizontal, r * el);
      hit->tangent_u = Vector3d(-sa, ca, 0.0);
      hit->tangent_v = Vector3d(-hit->n.z() * ca, -hit->n.z() * sa, horizontal);
      return;
    }
  }
}

template <bool kAnyHit>
bool SimWorld::Traverse(const Vector3d& o, const Vector3d& d, double t_min, double t_max,
                        RayHit* hit) const {
  if (grid_nx_ == 0) return false;
  double t0 = t_min, t1 = t_max;
  // Clip to the slab holding every object and to the grid bounds.
  auto clip = [&](double origin, double dir, double lo, double hi) {
    if (std::fabs(dir) < 1e-15) {
      if (origin < lo || origin > hi) t1 = -kInf;
      return;
    }
    double ta = (lo - origin) / dir, tb = (hi - origin) / dir;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  };
  // Each clip only narrows (t0, t1): stop as soon as it is empty.
  clip(o.z(), d.z(), -1e-9, max_z_ + 1e-9);
  if (!(t0 < t1)) return false;
  clip(o.x(), d.x(), grid_x0_, grid_x0_ + grid_nx_ * cell_m_);
  clip(o.y(), d.y(), grid_y0_, grid_y0_ + grid_ny_ * cell_m_);
  if (!(t0 < t1)) return false;
  const Vector3d pe = o + t0 * d;
  // The entry cell, clamped to the grid. Clamping before truncating gives
  // the same cell as flooring first: below 0 both end at 0.
  auto entry_cell = [this](double offset, int n) {
    const double q = cell_is_pow2_ ? offset * inv_cell_m_ : offset / cell_m_;
    return static_cast<int>(std::clamp(q, 0.0, n - 1.0));
  };
  int ix = entry_cell(pe.x() - grid_x0_, grid_nx_);
  int iy = entry_cell(pe.y() - grid_y0_, grid_ny_);
  const int step_x = d.x() > 0 ? 1 : -1;
  const int step_y = d.y() > 0 ? 1 : -1;
  double t_next_x = kInf, t_next_y = kInf, dt_x = kInf, dt_y = kInf;
  if (std::fabs(d.x()) > 1e-15) {
    t_next_x = (grid_x0_ + (ix + (d.x() > 0 ? 1 : 0)) * cell_m_ - o.x()) / d.x();
    dt_x = cell_m_ / std::fabs(d.x());
  }
  if (std::fabs(d.y()) > 1e-15) {
    t_next_y = (grid_y0_ + (iy + (d.y() > 0 ? 1 : 0)) * cell_m_ - o.y()) / d.y();
    dt_y = cell_m_ / std::fabs(d.y());
  }
  double best = t_max;
  int best_object = -1, best_face = -1;
  constexpr int kMailbox = 8;
  uint32_t mailbox[kMailbox];
  std::fill(mailbox, mailbox + kMailbox, std::numeric_limits<uint32_t>::max());
  int mailbox_next = 0;
  double t_cell = t0;  // where the ray enters the current cell
  while (true) {
    const size_t cell = static_cast<size_t>(iy) * grid_nx_ + ix;
    const double t_exit = std::min(t_next_x, t_next_y);
    const uint32_t k_begin = cell_start_[cell], k_end = cell_start_[cell + 1];
    // Most cells are empty; of the others, skip those where the ray passes
    // above everything in them.
    const bool test_cell =
        k_begin != k_end &&
        !(std::min(o.z() + t_cell * d.z(), o.z() + std::min(t_exit, t1) * d.z()) > cell_top_[cell]);
    for (uint32_t k = k_begin; test_cell && k < k_end; ++k) {
      // Mailbox: objects spanning several cells are tested once per ray.
      const uint32_t object = cell_items_[k];
      bool tested = false;
      for (int m = 0; m < kMailbox; ++m) tested = tested || mailbox[m] == object;
      if (tested) continue;
      mailbox[mailbox_next] = object;
      mailbox_next = (mailbox_next + 1) % kMailbox;
      int face = -1;
      const double t = IntersectObject(static_cast<int>(object), o, d, t_min, best, &face);
      if (t < best) {
        if (kAnyHit) return true;
        best = t;
        best_object = static_cast<int>(object);
        best_face = face;
      }
    }
    if ((best_object >= 0 && best <= t_exit) || t_exit >= t1) break;
    t_cell = t_exit;
    if (t_next_x < t_next_y) {
      ix += step_x;
      if (ix < 0 || ix >= grid_nx_) break;
      t_next_x += dt_x;
    } else {
      iy += step_y;
      if (iy < 0 || iy >= grid_ny_) break;
      t_next_y += dt_y;
    }
  }
  if (best_object < 0) return false;
  FillHit(best_object, best_face, o, d, best, hit);
  return true;
}

bool SimWorld::Cast(const Vector3d& origin, const Vector3d& dir, double t_max, RayHit* hit,
                    double t_min) const {
  bool found = false;
  if (dir.z() < -1e-15) {
    const double t = -origin.z() / dir.z();
    if (t > t_min && t < t_max) {
      t_max = t;
      found = true;
      hit->t = t;
      hit->object = -1;
      hit->surface = 0;
      hit->p = origin + t * dir;
      hit->p.z() = 0.0;
      hit->n = Vector3d::UnitZ();
      hit->uv = hit->p.head<2>();
      hit->tangent_u = Vector3d::UnitX();
      hit->tangent_v = Vector3d::UnitY();
    }
  }
  RayHit object_hit;
  if (Traverse<false>(origin, dir, t_min, t_max, &object_hit)) {
    *hit = object_hit;
    found = true;
  }
  return found;
}

bool SimWorld::Occluded(const Vector3d& origin, const Vector3d& dir, double t_max,
                        double t_min) const {
  if (dir.z() < -1e-15) {
    const double t = -origin.z() / dir.z();
    if (t > t_min && t < t_max) return true;
  }
  return Traverse<true>(origin, dir, t_min, t_max, nullptr);
}

Vector3f SimWorld::Albedo(const RayHit& hit, double footprint_m, const Vector2d& major_uv,
                          int taps) const {
  return surfaces_[static_cast<size_t>(hit.surface)].Albedo(hit.uv, footprint_m, major_uv, taps,
                                                            images_);
}

float SimWorld::Irradiance(const RayHit& hit, bool* in_shadow) const {
  const double cos_sun = hit.n.dot(sun_);
  bool shadow = cos_sun <= 0.0;
  if (!shadow && options_.shadows) {
    const Vector3d origin = hit.p + 1e-6 * hit.n;
    shadow = !SunSurelyVisible(origin) && Occluded(origin, sun_, 1e4, 1e-6);
  }
  if (in_shadow) *in_shadow = shadow;
  // Sky light from the upper hemisphere, a little ground bounce from below.
  const double sky = options_.ambient * (0.65 + 0.35 * hit.n.z());
  return static_cast<float>(sky + (shadow ? 0.0 : cos_sun));
}

Vector3f SimWorld::Sky(const Vector3d& dir) const {
  const float up = static_cast<float>(std::clamp(dir.z(), 0.0, 1.0));
  const Vector3f horizon(1.25f, 1.25f, 1.3f), zenith(0.55f, 0.75f, 1.15f);
  return horizon + std::sqrt(up) * (zenith - horizon);
}

// ---------------------------------------------------------------------------
// Procedural generation

SimWorld SimWorld::Generate(const WorldOptions& options, uint64_t seed,
                            const std::vector<KeepOutPath>& keep_out) {
  SimWorld world(seed, options);
  SimRandom rng(seed, "world");
  std::vector<Footprint> placed;
  const double x_lo = options.center_x_m - 0.5 * options.size_x_m;
  const double x_hi = options.center_x_m + 0.5 * options.size_x_m;
  const double y_lo = options.center_y_m - 0.5 * options.size_y_m;
  const double y_hi = options.center_y_m + 0.5 * options.size_y_m;

  auto is_clear = [&](const Vector2d& c, double radius, double top_z, double gap) {
    for (const KeepOutPath& k : keep_out) {
      if (top_z < k.below_z) continue;
      const double limit2 = (radius + k.radius_m) * (radius + k.radius_m);
      for (const Vector2d& p : k.points) {
        if ((p - c).squaredNorm() < limit2) return false;
      }
    }
    for (const Footprint& f : placed) {
      if ((f.center - c).norm() < radius + f.radius + gap) return false;
    }
    return true;
  };
  auto random_in_area = [&](double margin) {
    return Vector2d(rng.Uniform(x_lo + margin, x_hi - margin),
                    rng.Uniform(y_lo + margin, y_hi - margin));
  };
  constexpr int kAttempts = 300;
  auto place_box = [&](const Vector2d& c, double sx, double sy, double h, double yaw,
                       MaterialKind side, MaterialKind top, double gap) {
    const double radius = 0.5 * std::hypot(sx, sy);
    if (!is_clear(c, radius, h, gap)) return false;
    SimObject o;
    o.shape = SimObject::Shape::kBox;
    o.center = Vector3d(c.x(), c.y(), 0.5 * h);
    o.half = Vector3d(0.5 * sx, 0.5 * sy, 0.5 * h);
    o.yaw = yaw;
    world.AddObject(o, side, top);
    placed.push_back({c, radius});
    return true;
  };
  auto place_cylinder = [&](const Vector2d& c, double r, double h, double z0, MaterialKind side,
                            MaterialKind top, double clear_radius, double top_z, double gap) {
    if (!is_clear(c, clear_radius, top_z, gap)) return false;
    SimObject o;
    o.shape = SimObject::Shape::kCylinder;
    o.center = Vector3d(c.x(), c.y(), z0 + 0.5 * h);
    o.half = Vector3d(r, r, 0.5 * h);
    world.AddObject(o, side, top);
    placed.push_back({c, clear_radius});
    return true;
  };
  auto facade = [&]() {
    const double u = rng.Uniform();
    return u < 0.4 ? MaterialKind::kBrick
                   : (u < 0.8 ? MaterialKind::kPlaster : MaterialKind::kConcrete);
  };
  auto place_tree = [&](const Vector2d& c, double gap) {
    const double trunk_r = rng.Uniform(0.12, 0.25);
    const double trunk_h = rng.Uniform(1.6, 2.6);
    const double canopy_r = rng.Uniform(1.2, 2.0);
    const double canopy_z = trunk_h + 0.6 * canopy_r;
    if (!is_clear(c, canopy_r, canopy_z + canopy_r, gap)) return false;
    SimObject trunk;
    trunk.shape = SimObject::Shape::kCylinder;
    const double trunk_top = trunk_h + 0.5 * canopy_r;  // ends inside the canopy
    trunk.center = Vector3d(c.x(), c.y(), 0.5 * trunk_top);
    trunk.half = Vector3d(trunk_r, trunk_r, 0.5 * trunk_top);
    world.AddObject(trunk, MaterialKind::kBark, MaterialKind::kBark);
    placed.push_back({c, canopy_r});
    SimObject canopy;
    canopy.shape = SimObject::Shape::kSphere;
    canopy.center = Vector3d(c.x(), c.y(), canopy_z);
    canopy.half = Vector3d::Constant(canopy_r);
    world.AddObject(canopy, MaterialKind::kFoliage, MaterialKind::kFoliage);
    return true;
  };

  for (int i = 0; i < options.buildings; ++i) {
    for (int a = 0; a < kAttempts; ++a) {
      const double sx = rng.Uniform(options.building_min_size_m, options.building_max_size_m);
      const double sy = rng.Uniform(options.building_min_size_m, options.building_max_size_m);
      const double h = rng.Uniform(options.building_min_height_m, options.building_max_height_m);
      const double yaw = rng.Uniform(0.0, 0.5 * M_PI);
      if (place_box(random_in_area(0.5 * std::max(sx, sy)), sx, sy, h, yaw, facade(),
                    MaterialKind::kRoof, 1.0))
        break;
    }
  }
  for (int i = 0; i < options.walls; ++i) {
    for (int a = 0; a < kAttempts; ++a) {
      const double length = rng.Uniform(3.0, 10.0);
      const double h = rng.Uniform(1.2, 3.0);
      const double u = rng.Uniform();
      const MaterialKind kind = u < 0.45 ? MaterialKind::kConcrete
                                         : (u < 0.75 ? MaterialKind::kBrick : MaterialKind::kWood);
      if (place_box(random_in_area(0.5 * length), length, rng.Uniform(0.15, 0.3), h,
                    rng.Uniform(0.0, M_PI), kind, kind, 0.5))
        break;
    }
  }
  for (int i = 0; i < options.trees; ++i) {
    for (int a = 0; a < kAttempts; ++a) {
      if (place_tree(random_in_area(2.0), 0.3)) break;
    }
  }
  for (int i = 0; i < options.poles; ++i) {
    for (int a = 0; a < kAttempts; ++a) {
      const double r = rng.Uniform(0.05, 0.12);
      const double h = rng.Uniform(2.5, 6.0);
      if (place_cylinder(random_in_area(1.0), r, h, 0.0, MaterialKind::kMetal, MaterialKind::kMetal,
                         r, h, 0.3))
        break;
    }
  }
  for (int i = 0; i < options.clutter; ++i) {
    for (int a = 0; a < kAttempts; ++a) {
      const Vector2d c = random_in_area(1.5);
      const double yaw = rng.Uniform(0.0, M_PI);
      const double u = rng.Uniform();
      bool ok;
      if (u < 0.3) {  // crate
        const double s = rng.Uniform(0.5, 1.2);
        ok = place_box(c, s, s * rng.Uniform(0.7, 1.3), s * rng.Uniform(0.6, 1.0), yaw,
                       MaterialKind::kWood, MaterialKind::kWood, 0.2);
      } else if (u < 0.45) {  // shipping container
        ok = place_box(c, 6.06, 2.44, 2.59, yaw, MaterialKind::kContainer, MaterialKind::kContainer,
                       0.5);
      } else if (u < 0.65) {  // barrel
        ok = place_cylinder(c, 0.3, 0.9, 0.0, MaterialKind::kMetal, MaterialKind::kMetal, 0.3, 0.9,
                            0.2);
      } else if (u < 0.85) {  // concrete block / barrier
        ok = place_box(c, rng.Uniform(1.0, 2.5), rng.Uniform(0.4, 1.0), rng.Uniform(0.5, 1.1), yaw,
                       MaterialKind::kConcrete, MaterialKind::kConcrete, 0.2);
      } else {  // cabinet
        ok = place_box(c, rng.Uniform(0.5, 1.0), rng.Uniform(0.3, 0.6), rng.Uniform(1.0, 1.8), yaw,
                       MaterialKind::kMetal, MaterialKind::kMetal, 0.2);
      }
      if (ok) break;
    }
  }
  if (options.perimeter) {
    // A ring of buildings and trees outside the area so the ground camera's
    // horizon is not an empty plane.
    const double perimeter = 2.0 * (options.size_x_m + options.size_y_m);
    double s = rng.Uniform(0.0, 4.0);
    while (s < perimeter) {
      Vector2d p, outward;
      if (s < options.size_x_m) {
        p = Vector2d(x_lo + s, y_lo);
        outward = -Vector2d::UnitY();
      } else if (s < options.size_x_m + options.size_y_m) {
        p = Vector2d(x_hi, y_lo + s - options.size_x_m);
        outward = Vector2d::UnitX();
      } else if (s < 2.0 * options.size_x_m + options.size_y_m) {
        p = Vector2d(x_hi - (s - options.size_x_m - options.size_y_m), y_hi);
        outward = Vector2d::UnitY();
      } else {
        p = Vector2d(x_lo, y_hi - (s - 2.0 * options.size_x_m - options.size_y_m));
        outward = -Vector2d::UnitX();
      }
      if (rng.Uniform() < 0.6) {
        const double w = rng.Uniform(6.0, 14.0), dpt = rng.Uniform(5.0, 10.0);
        const double yaw = std::atan2(outward.y(), outward.x()) + rng.Uniform(-0.15, 0.15);
        place_box(p + outward * (0.5 * dpt + rng.Uniform(2.0, 6.0)), dpt, w, rng.Uniform(4.0, 12.0),
                  yaw, facade(), MaterialKind::kRoof, 0.5);
        s += 0.5 * w + rng.Uniform(3.0, 8.0);
      } else {
        place_tree(p + outward * rng.Uniform(2.5, 6.0), 0.2);
        s += rng.Uniform(3.0, 7.0);
      }
    }
  }
  world.BuildIndex();
  // The ground's slowly varying fields, tabulated over the area and well
  // beyond (the ground camera sees far).
  constexpr double kMargin = 40.0;
  world.surfaces_[0].PrecomputeGround(x_lo - kMargin, y_lo - kMargin, x_hi + kMargin,
                                      y_hi + kMargin, 0.25);
  return world;
}

}  // namespace ag
