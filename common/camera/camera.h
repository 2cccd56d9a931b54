#pragma once

#include <Eigen/Core>
#include <cmath>

#include "common/camera/camera_params.h"

namespace ag {

/// A calibrated camera: pinhole with radial-tangential distortion (OpenCV's
/// cv::projectPoints model, k1 k2 p1 p2 [k3]) or equidistant fisheye (OpenCV's
/// cv::fisheye model, k1..k4). Pixels: x right, y down; camera frame: x
/// right, y down, z forward.
class Camera {
 public:
  /// Smallest depth (m) Project accepts: nearer points have no meaningful
  /// projection (and ProjectT divides by z).
  static constexpr double kMinDepth = 1e-6;

  /// Validates `params` (model name, size > 0, focal lengths > 0, finite
  /// values, distortion count for the model) and throws ag::OptionError
  /// naming the field otherwise.
  explicit Camera(const CameraParams& params);

  const CameraParams& params() const { return params_; }
  int width() const { return params_.width; }
  int height() const { return params_.height; }
  bool is_fisheye() const { return fisheye_; }

  /// Projects a point in the camera frame to distorted pixel coordinates.
  /// Returns false (and leaves *uv unchanged) when the point is not in front
  /// of the camera (z < kMinDepth, for both models: the equidistant model as
  /// written divides by z too) or is not finite. Does not check image bounds
  /// (see InImage). Equal to ProjectT<double>.
  bool Project(const Eigen::Vector3d& p_c, Eigen::Vector2d* uv) const;

  /// Templated projection for Ceres autodiff functors; same model as Project.
  /// No validity check (callers keep points in front of the camera).
  template <typename T>
  void ProjectT(const T* p_c, T* uv) const;

  /// Pixel to the undistorted normalised image plane (x/z, y/z), by
  /// iterative inversion of the distortion (Gauss-Newton on the 2x2
  /// Jacobian from a closed-form or radial initial guess; converges to
  /// < 1e-10 px reprojection error within the image for realistic
  /// distortion). Where the distortion is not invertible (far outside the
  /// image) it returns the best point found.
  Eigen::Vector2d UndistortToNormalized(const Eigen::Vector2d& uv) const;

  /// Pixel to a unit-norm bearing vector in the camera frame.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& uv) const;

  /// Undistorted pixel (as an ideal pinhole with the same fx fy cx cy would
  /// see it) of a distorted pixel.
  Eigen::Vector2d UndistortPixel(const Eigen::Vector2d& uv) const;

  /// True when uv lies inside [border, width-1-border] x [border, height-1-border].
  bool InImage(const Eigen::Vector2d& uv, double border = 0.0) const;

 private:
  CameraParams params_;
  bool fisheye_ = false;
  double d_[5] = {0, 0, 0, 0, 0};  ///< distortion padded with zeros
};

template <typename T>
void Camera::ProjectT(const T* p_c, T* uv) const {
  using std::atan2;
  using std::sqrt;
  const T x = p_c[0] / p_c[2];
  const T y = p_c[1] / p_c[2];
  T xd, yd;
  if (fisheye_) {
    const T r2 = x * x + y * y;
    // atan(r) with a safe derivative at r = 0.
    if (r2 < T(1e-18)) {
      xd = x;
      yd = y;
    } else {
      const T r = sqrt(r2);
      const T theta = atan2(r, T(1.0));
      const T t2 = theta * theta;
      const T theta_d =
          theta * (T(1.0) + t2 * (T(d_[0]) + t2 * (T(d_[1]) + t2 * (T(d_[2]) + t2 * T(d_[3])))));
      xd = x * theta_d / r;
      yd = y * theta_d / r;
    }
  } else {
    const T r2 = x * x + y * y;
    const T radial = T(1.0) + r2 * (T(d_[0]) + r2 * (T(d_[1]) + r2 * T(d_[4])));
    xd = x * radial + T(2.0 * d_[2]) * x * y + T(d_[3]) * (r2 + T(2.0) * x * x);
    yd = y * radial + T(d_[2]) * (r2 + T(2.0) * y * y) + T(2.0 * d_[3]) * x * y;
  }
  uv[0] = T(params_.fx) * xd + T(params_.cx);
  uv[1] = T(params_.fy) * yd + T(params_.cy);
}

}  // namespace ag
