#include "common/camera/camera.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <string>

#include "common/core/error.h"

namespace ag {
namespace {

bool AllFinite(const CameraParams& p) {
  return std::isfinite(p.fx) && std::isfinite(p.fy) && std::isfinite(p.cx) && std::isfinite(p.cy);
}

/// d(distorted normalised point)/d(undistorted normalised point), the same
/// model as Camera::ProjectT without the intrinsics. `d` is the padded
/// distortion (radtan: k1 k2 p1 p2 k3; equidistant: k1 k2 k3 k4).
Eigen::Matrix2d DistortionJacobian(bool fisheye, const double* d, double x, double y) {
  Eigen::Matrix2d J;
  const double r2 = x * x + y * y;
  if (fisheye) {
    if (r2 < 1e-18) return Eigen::Matrix2d::Identity();  // theta_d / r -> 1 (ProjectT's branch)
    // xd = g(r) x with g = theta_d(theta(r)) / r and theta = atan(r), so
    // J = g I + g'(r) x x^T / r.
    const double r = std::sqrt(r2);
    const double theta = std::atan(r);
    const double t2 = theta * theta;
    const double theta_d = theta * (1.0 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))));
    const double dtheta_d =
        1.0 + t2 * (3.0 * d[0] + t2 * (5.0 * d[1] + t2 * (7.0 * d[2] + t2 * 9.0 * d[3])));
    const double dtheta_dr = 1.0 / (1.0 + r2);
    const double g = theta_d / r;
    const double dg_dr = (dtheta_d * dtheta_dr * r - theta_d) / r2;
    const Eigen::Vector2d p(x, y);
    J = g * Eigen::Matrix2d::Identity() + (dg_dr / r) * p * p.transpose();
    return J;
  }
  const double k1 = d[0], k2 = d[1], p1 = d[2], p2 = d[3], k3 = d[4];
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  const double dradial_dr2 = k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3);
  J(0, 0) = radial + 2.0 * x * x * dradial_dr2 + 2.0 * p1 * y + 6.0 * p2 * x;
  J(0, 1) = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y;
  J(1, 0) = 2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y;
  J(1, 1) = radial + 2.0 * y * y * dradial_dr2 + 6.0 * p1 * y + 2.0 * p2 * x;
  return J;
}

/// Initial guess for the equidistant inversion: the model is radially
/// symmetric, so solving theta_d(theta) = |x_d| in 1-D (Newton from
/// theta = theta_d, OpenCV's approach) is already close to the answer.
Eigen::Vector2d FisheyeInitialGuess(const double* d, const Eigen::Vector2d& xd) {
  const double theta_d = xd.norm();
  if (theta_d < 1e-9) return xd;
  constexpr double kMaxTheta = 0.5 * M_PI - 1e-3;  // tan() must stay finite
  double theta = std::min(theta_d, kMaxTheta);
  for (int i = 0; i < 10; ++i) {
    const double t2 = theta * theta;
    const double f = theta * (1.0 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3])))) - theta_d;
    const double df =
        1.0 + t2 * (3.0 * d[0] + t2 * (5.0 * d[1] + t2 * (7.0 * d[2] + t2 * 9.0 * d[3])));
    if (!(std::abs(df) > 1e-12)) break;
    theta = std::clamp(theta - f / df, 0.0, kMaxTheta);
  }
  return xd * (std::tan(theta) / theta_d);
}

}  // namespace

Camera::Camera(const CameraParams& params) : params_(params) {
  const CameraParams& p = params_;
  CheckOption(p.model == "pinhole" || p.model == "equidistant", "model",
              "must be 'pinhole' or 'equidistant', got '" + p.model + "'");
  fisheye_ = p.model == "equidistant";
  CheckOption(p.width > 0, "width", "must be > 0, got " + std::to_string(p.width));
  CheckOption(p.height > 0, "height", "must be > 0, got " + std::to_string(p.height));
  CheckOption(AllFinite(p), "intrinsics", "must be finite");
  CheckOption(
      p.fx > 0 && p.fy > 0, "intrinsics",
      "focal lengths must be > 0, got fx " + std::to_string(p.fx) + " fy " + std::to_string(p.fy));
  const size_t n = p.distortion.size();
  if (fisheye_) {
    CheckOption(n == 0 || n == 4, "distortion",
                "equidistant needs 4 values, got " + std::to_string(n));
  } else {
    CheckOption(n == 0 || n == 4 || n == 5, "distortion",
                "pinhole (radtan) needs 4 or 5 values, got " + std::to_string(n));
  }
  for (size_t i = 0; i < n; ++i) {
    CheckOption(std::isfinite(p.distortion[i]), "distortion",
                "value " + std::to_string(i) + " is not finite");
    d_[i] = p.distortion[i];
  }
}

bool Camera::Project(const Eigen::Vector3d& p_c, Eigen::Vector2d* uv) const {
  if (!p_c.allFinite() || p_c.z() < kMinDepth) return false;
  Eigen::Vector2d out;
  ProjectT(p_c.data(), out.data());
  if (!out.allFinite()) return false;
  *uv = out;
  return true;
}

Eigen::Vector2d Camera::UndistortToNormalized(const Eigen::Vector2d& uv) const {
  const Eigen::Vector2d xd((uv.x() - params_.cx) / params_.fx, (uv.y() - params_.cy) / params_.fy);
  Eigen::Vector2d x = fisheye_ ? FisheyeInitialGuess(d_, xd) : xd;
  const Eigen::Vector2d focal(params_.fx, params_.fy);

  // Residual in pixels through ProjectT itself, so the fixed point is exactly
  // what Project maps back to uv.
  auto residual = [&](const Eigen::Vector2d& x_n) {
    const double p[3] = {x_n.x(), x_n.y(), 1.0};
    Eigen::Vector2d projected;
    ProjectT(p, projected.data());
    return Eigen::Vector2d(projected - uv);
  };

  Eigen::Vector2d e = residual(x);
  double cost = e.squaredNorm();
  constexpr int kMaxIterations = 30;
  constexpr double kTolerancePx = 1e-12;
  for (int it = 0; it < kMaxIterations && std::sqrt(cost) > kTolerancePx; ++it) {
    const Eigen::Matrix2d J = focal.asDiagonal() * DistortionJacobian(fisheye_, d_, x.x(), x.y());
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-300)) break;
    const Eigen::Vector2d step = -J.inverse() * e;
    // Backtracking keeps the iteration from jumping to another branch of
    // the (non-monotonic far outside the image) distortion polynomial.
    bool improved = false;
    for (double alpha = 1.0; alpha > 1e-4; alpha *= 0.5) {
      const Eigen::Vector2d candidate = x + alpha * step;
      const Eigen::Vector2d e_candidate = residual(candidate);
      const double cost_candidate = e_candidate.squaredNorm();
      if (std::isfinite(cost_candidate) && cost_candidate < cost) {
        x = candidate;
        e = e_candidate;
        cost = cost_candidate;
        improved = true;
        break;
      }
    }
    if (!improved) break;
  }
  return x;
}

Eigen::Vector3d Camera::Unproject(const Eigen::Vector2d& uv) const {
  return UndistortToNormalized(uv).homogeneous().normalized();
}

Eigen::Vector2d Camera::UndistortPixel(const Eigen::Vector2d& uv) const {
  const Eigen::Vector2d x = UndistortToNormalized(uv);
  return Eigen::Vector2d(params_.fx * x.x() + params_.cx, params_.fy * x.y() + params_.cy);
}

bool Camera::InImage(const Eigen::Vector2d& uv, double border) const {
  return uv.x() >= border && uv.y() >= border && uv.x() <= params_.width - 1 - border &&
         uv.y() <= params_.height - 1 - border;
}

}  // namespace ag
