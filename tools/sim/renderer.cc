#include "tools/sim/renderer.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace ag {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kDeg = M_PI / 180.0;

// Extra samples on edges (px), with the pixel centre they make a 4-sample
// pattern with distinct rows and columns.
constexpr double kSubsamples[3][2] = {{0.375, -0.125}, {-0.125, -0.375}, {-0.375, 0.125}};

float Luminance(const Vector3f& c) { return 0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z(); }

}  // namespace

void CameraSimOptions::Check() const {
  CheckOption(model == "pinhole" || model == "equidistant", "model",
              "must be pinhole or equidistant");
  CheckOption(width >= 8 && height >= 8, "width", "image must be at least 8 x 8");
  CheckOption(fx > 0 && fy > 0, "fx", "focal lengths must be > 0");
  CheckOption(rate_hz > 0 && rate_hz <= 100, "rate_hz", "must be in (0, 100]");
  CheckOption(position_m.size() == 3, "position_m", "must be [x, y, z]");
  CheckOption(exposure_target > 0 && exposure > 0, "exposure",
              "exposure and exposure_target must be > 0");
  CheckOption(exposure_jitter >= 0 && exposure_jitter < 0.5, "exposure_jitter",
              "must be in [0, 0.5)");
  CheckOption(vignetting >= 0 && vignetting < 1, "vignetting", "must be in [0, 1)");
  CheckOption(blur_sigma_px >= 0 && blur_sigma_px < 10, "blur_sigma_px", "must be in [0, 10)");
  CheckOption(read_noise_dn >= 0 && shot_noise_dn >= 0, "read_noise_dn", "noise must be >= 0");
  CheckOption(gamma >= 1 && gamma <= 3, "gamma", "must be in [1, 3]");
  CheckOption(max_aniso >= 1 && max_aniso <= 16, "max_aniso", "must be in [1, 16]");
}

CameraParams CameraSimOptions::Params() const {
  CameraParams p;
  p.model = model;
  p.width = width;
  p.height = height;
  p.fx = fx;
  p.fy = fy;
  p.cx = cx;
  p.cy = cy;
  p.distortion = distortion;
  return p;
}

Pose CameraSimOptions::NominalBodyCamera() const {
  Eigen::Matrix3d R0;
  R0.col(0) = Vector3d(0, -1, 0);  // camera x (right) = body -y
  R0.col(1) = Vector3d(0, 0, -1);  // camera y (down) = body -z
  R0.col(2) = Vector3d(1, 0, 0);   // camera z (forward) = body x
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * kDeg, Vector3d::UnitZ()).toRotationMatrix() *
               Eigen::AngleAxisd(pitch_down_deg * kDeg, Vector3d::UnitY()).toRotationMatrix() * R0 *
               Eigen::AngleAxisd(roll_deg * kDeg, Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Vector3d(position_m[0], position_m[1], position_m[2]);
  return T;
}

CameraRenderer::CameraRenderer(const CameraSimOptions& options)
    : options_(options), camera_(options.Params()) {
  const int w = options_.width, h = options_.height;
  bearings_.resize(static_cast<size_t>(w) * h);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u)
      bearings_[static_cast<size_t>(v) * w + u] = camera_.Unproject(Vector2d(u, v));
  }
  gamma_lut_.resize(kGammaLutSize);
  for (size_t i = 0; i < kGammaLutSize; ++i) {
    const double x = static_cast<double>(i) / (kGammaLutSize - 1);
    gamma_lut_[i] = static_cast<uint8_t>(std::lround(255.0 * std::pow(x, 1.0 / options_.gamma)));
  }
  pixel_angle_.resize(bearings_.size());
  vignette_.resize(bearings_.size());
  const double r_corner = std::hypot(std::max(options_.cx, w - 1 - options_.cx),
                                     std::max(options_.cy, h - 1 - options_.cy));
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      const size_t j = u + 1 < w ? i + 1 : i - 1;
      const size_t k = v + 1 < h ? i + w : i - w;
      // Geometric mean of the horizontal and vertical angular pixel size.
      const double ax = std::acos(std::clamp(bearings_[i].dot(bearings_[j]), -1.0, 1.0));
      const double ay = std::acos(std::clamp(bearings_[i].dot(bearings_[k]), -1.0, 1.0));
      pixel_angle_[i] = static_cast<float>(std::sqrt(ax * ay));
      const double r = std::hypot(u - options_.cx, v - options_.cy) / r_corner;
      vignette_[i] = static_cast<float>(1.0 - options_.vignetting * r * r);
    }
  }
}

Vector3d CameraRenderer::Bearing(double u, double v) const {
  // Bilinear in the table of exact bearings: within a pixel the error is far
  // below a micro-radian, and this is only used for sub-pixel samples.
  const int w = options_.width, h = options_.height;
  const int u0 = std::clamp(static_cast<int>(std::floor(u)), 0, w - 2);
  const int v0 = std::clamp(static_cast<int>(std::floor(v)), 0, h - 2);
  const double fu = u - u0, fv = v - v0;
  const size_t i = static_cast<size_t>(v0) * w + u0;
  const Vector3d a = bearings_[i] + fu * (bearings_[i + 1] - bearings_[i]);
  const Vector3d b = bearings_[i + w] + fu * (bearings_[i + w + 1] - bearings_[i + w]);
  return (a + fv * (b - a)).normalized();
}

Vector3f CameraRenderer::Shade(const SimWorld& world, const Vector3d& origin, const Vector3d& dir_w,
                               double pixel_angle, RayHit* hit, bool* found, bool* shadow,
                               int max_taps) const {
  *found = world.Cast(origin, dir_w, 1e5, hit);
  if (!*found) {
    *shadow = false;
    return world.Sky(dir_w);
  }
  // Pixel footprint on the surface: `minor` across the ray, stretched by
  // 1 / cos(incidence) along the ray's projection (anisotropic filtering:
  // several samples along the long axis, each filtered to its share).
  const double minor = hit->t * pixel_angle;
  const double cos_inc = std::max(std::fabs(hit->n.dot(dir_w)), 0.02);
  const double major = minor / cos_inc;
  int n = std::clamp(static_cast<int>(std::ceil(1.0 / cos_inc - 0.5)), 1,
                     std::min(options_.max_aniso, max_taps));
  Vector2d axis(dir_w.dot(hit->tangent_u), dir_w.dot(hit->tangent_v));
  if (axis.norm() < 1e-9) n = 1;
  const Vector3f albedo = n == 1 ? world.Albedo(*hit, std::max(minor, major))
                                 : world.Albedo(*hit, minor, major * axis.normalized(), n);
  return albedo * world.Irradiance(*hit, shadow);
}

double CameraRenderer::DepthAt(const SimWorld& world, const Pose& T_W_camera, int u, int v) const {
  const Vector3d& b = bearings_[static_cast<size_t>(v) * options_.width + u];
  RayHit hit;
  if (!world.Cast(T_W_camera.translation(), T_W_camera.linear() * b, 1e5, &hit)) return 0.0;
  return hit.t * b.z();
}

CameraRenderer::Frame CameraRenderer::Render(const SimWorld& world, const Pose& T_W_camera,
                                             SimRandom& rng) const {
  const int w = options_.width, h = options_.height;
  const size_t n = static_cast<size_t>(w) * h;
  const Eigen::Matrix3d R = T_W_camera.linear();
  const Vector3d o = T_W_camera.translation();
  std::vector<Vector3f> radiance(n);
  std::vector<int> id(n);
  std::vector<uint8_t> shadow(n);
  Frame frame;
  frame.depth = cv::Mat(h, w, CV_32FC1);
  RayHit hit;
  for (int v = 0; v < h; ++v) {
    auto* depth_row = frame.depth.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      bool found = false, in_shadow = false;
      radiance[i] = Shade(world, o, R * bearings_[i], pixel_angle_[i], &hit, &found, &in_shadow);
      depth_row[u] = found ? static_cast<float>(hit.t * bearings_[i].z()) : 0.0f;
      id[i] = found ? hit.surface + 1 : 0;
      shadow[i] = in_shadow ? 1 : 0;
    }
  }
  if (options_.supersample_edges) {
    // Edges: another surface (every solid is convex, so a geometric edge
    // always separates two surfaces, or a surface and the sky) or a shadow
    // boundary between neighbours. Only those pixels get extra samples.
    std::vector<uint8_t> edge(n, 0);
    auto differs = [&](size_t a, size_t b) { return id[a] != id[b] || shadow[a] != shadow[b]; };
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const size_t i = static_cast<size_t>(v) * w + u;
        if (u + 1 < w && differs(i, i + 1)) edge[i] = edge[i + 1] = 1;
        if (v + 1 < h && differs(i, i + w)) edge[i] = edge[i + w] = 1;
      }
    }
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const size_t i = static_cast<size_t>(v) * w + u;
        if (!edge[i]) continue;
        Vector3f sum = radiance[i];
        for (const auto& s : kSubsamples) {
          bool found = false, in_shadow = false;
          sum += Shade(world, o, R * Bearing(u + s[0], v + s[1]), 0.5 * pixel_angle_[i], &hit,
                       &found, &in_shadow, /*max_taps=*/1);
        }
        radiance[i] = 0.25f * sum;
      }
    }
  }

  // Sensor: exposure, vignetting, optical blur, noise, gamma.
  const int channels = options_.color ? 3 : 1;
  cv::Mat linear(h, w, channels == 3 ? CV_32FC3 : CV_32FC1);
  double sum_lum = 0.0;
  for (size_t i = 0; i < n; ++i) sum_lum += Luminance(radiance[i]);
  double gain = options_.exposure;
  if (options_.auto_exposure)
    gain *= options_.exposure_target / std::max(sum_lum / static_cast<double>(n), 1e-3);
  gain *= 1.0 + options_.exposure_jitter * rng.Gaussian();
  for (int v = 0; v < h; ++v) {
    float* row = linear.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      const size_t i = static_cast<size_t>(v) * w + u;
      const float g = static_cast<float>(gain) * vignette_[i];
      if (channels == 3) {
        row[3 * u + 0] = g * radiance[i].z();  // OpenCV order: BGR
        row[3 * u + 1] = g * radiance[i].y();
        row[3 * u + 2] = g * radiance[i].x();
      } else {
        row[u] = g * Luminance(radiance[i]);
      }
    }
  }
  if (options_.blur_sigma_px > 0.0) {
    cv::GaussianBlur(linear, linear, cv::Size(0, 0), options_.blur_sigma_px, options_.blur_sigma_px,
                     cv::BORDER_REFLECT101);
  }
  frame.image = cv::Mat(h, w, channels == 3 ? CV_8UC3 : CV_8UC1);
  const double read2 = options_.read_noise_dn * options_.read_noise_dn;
  for (int v = 0; v < h; ++v) {
    const float* in = linear.ptr<float>(v);
    uint8_t* out = frame.image.ptr<uint8_t>(v);
    for (int k = 0; k < w * channels; ++k) {
      double dn = 255.0 * std::clamp(static_cast<double>(in[k]), 0.0, 1.0);
      dn += std::sqrt(options_.shot_noise_dn * dn + read2) * rng.Gaussian();
      const double x = std::clamp(dn / 255.0, 0.0, 1.0);
      // std::lround (halves away from zero) of a value >= 0, inline: this
      // runs for every pixel and channel.
      const double lut_x = x * (kGammaLutSize - 1);
      const double whole = std::trunc(lut_x);
      out[k] = gamma_lut_[static_cast<size_t>(whole) + (lut_x - whole >= 0.5 ? 1 : 0)];
    }
  }
  return frame;
}

}  // namespace ag
