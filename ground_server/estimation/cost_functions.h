#pragma once

// Ceres residuals of the two refinement stages (paper, Section "Two-stage
// Optimization"). Conventions: a 6-DoF pose T_w_c is two parameter blocks,
// an Eigen quaternion q (x, y, z, w; ceres::EigenQuaternionManifold) and a
// translation t; the 4-DoF T_wa_wg is one block (x, y, z, yaw). Residuals are
// whitened by their standard deviation (sqrt information) so that robust
// losses and covariances are in consistent units. Include only from .cc files
// (Ceres headers are kept out of the rest of the build).

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>

#include "common/camera/camera.h"
#include "ground_server/estimation/camera_rotation.h"
#include "ground_server/estimation/refinement.h"

namespace ag {

/// The robust loss of RobustLossOptions (nullptr for "none"); Ceres owns it.
inline ceres::LossFunction* MakeLoss(const RobustLossOptions& o) {
  if (o.type == "huber") return new ceres::HuberLoss(o.scale);
  if (o.type == "cauchy") return new ceres::CauchyLoss(o.scale);
  return nullptr;
}

/// [x]x, the cross-product matrix: [x]x v = x.cross(v).
inline Eigen::Matrix3d Skew(const Eigen::Vector3d& x) {
  Eigen::Matrix3d S;
  S << 0, -x.z(), x.y(), x.z(), 0, -x.x(), -x.y(), x.x(), 0;
  return S;
}

/// Stage 1, eq. (r_GC): UGV reprojection of a map point in inverse-depth
/// form. The point is anchored in its host keyframe h, where it was first
/// seen at undistorted normalised coordinates f_h = (x, y, 1); with inverse
/// depth rho,
///   p_wg = R_h * f_h / rho + t_h,   p_cj = R_j^T (p_wg - t_j),
///   r = (K_j(p_cj) - u_j) / sigma_px.
/// Parameters: q_h, t_h, q_j, t_j, rho. Inverse depth keeps far points well
/// conditioned (paper: "for numerical stability"). Stage 1 uses
/// InverseDepthReprojectionCost below (the same residual, analytic
/// Jacobians); this autodiff form is the reference the tests and
/// stage1_bench hold it to.
struct InverseDepthReprojectionError {
  InverseDepthReprojectionError(const Camera* camera, const Eigen::Vector2d& f_h,
                                const Eigen::Vector2d& u_j, double sigma_px)
      : camera_(camera), f_h_(f_h), u_j_(u_j), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* q_h, const T* t_h, const T* q_j, const T* t_j, const T* rho,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> R_h(q_h);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_h(t_h);
    const Eigen::Map<const Eigen::Quaternion<T>> R_j(q_j);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_j(t_j);
    const Eigen::Matrix<T, 3, 1> f(T(f_h_.x()), T(f_h_.y()), T(1.0));
    const Eigen::Matrix<T, 3, 1> p_wg = R_h * (f / rho[0]) + p_h;
    const Eigen::Matrix<T, 3, 1> p_cj = R_j.conjugate() * (p_wg - p_j);
    if (p_cj.z() <= T(1e-3)) return false;  // behind the camera: step rejected
    T uv[2];
    camera_->ProjectT(p_cj.data(), uv);
    residual[0] = (uv[0] - T(u_j_.x())) * inv_sigma_;
    residual[1] = (uv[1] - T(u_j_.y())) * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(const Camera* camera, const Eigen::Vector2d& f_h,
                                     const Eigen::Vector2d& u_j, double sigma_px) {
    return new ceres::AutoDiffCostFunction<InverseDepthReprojectionError, 2, 4, 3, 4, 3, 1>(
        new InverseDepthReprojectionError(camera, f_h, u_j, sigma_px));
  }

 private:
  const Camera* camera_;
  Eigen::Vector2d f_h_;
  Eigen::Vector2d u_j_;
  double inv_sigma_;
};

/// InverseDepthReprojectionError with analytic Jacobians (stage 1 spends
/// most of its solve differentiating this residual with 15-wide jets). The
/// rotations are differentiated as Eigen applies a quaternion (x, y, z, w)
/// = (u, w) to a vector, v + 2w (u x v) + 2 u x (u x v), so the Jacobians
/// equal autodiff's in the quaternions' ambient coordinates; only the
/// camera's projection is left to a 3-wide jet. Same residual, same
/// parameters, same rejection of points behind the camera.
class InverseDepthReprojectionCost final : public ceres::SizedCostFunction<2, 4, 3, 4, 3, 1> {
 public:
  InverseDepthReprojectionCost(const Camera* camera, const Eigen::Vector2d& f_h,
                               const Eigen::Vector2d& u_j, double sigma_px)
      : camera_(camera), f_h_(f_h), u_j_(u_j), inv_sigma_(1.0 / sigma_px) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    using Mat3 = Eigen::Matrix3d;
    using Vec3 = Eigen::Vector3d;
    const Eigen::Map<const Vec3> u_h(parameters[0]), t_h(parameters[1]);
    const Eigen::Map<const Vec3> u_j(parameters[2]), t_j(parameters[3]);
    const double w_h = parameters[0][3], w_j = parameters[2][3], rho = parameters[4][0];
    const Vec3 f(f_h_.x(), f_h_.y(), 1.0);
    const Vec3 v = f / rho;
    // Rotation by (u, w) as a matrix acting on vectors (Eigen's formula is
    // linear in the vector); the conjugate is (-u, w).
    const auto rotation = [](const Vec3& u, double w) {
      const Mat3 U = Skew(u);
      return Mat3(Mat3::Identity() + 2 * w * U + 2 * U * U);
    };
    const Mat3 R_h = rotation(u_h, w_h);
    const Mat3 Rt_j = rotation(-u_j, w_j);
    const Vec3 d = R_h * v + t_h - t_j;
    const Vec3 p = Rt_j * d;
    if (p.z() <= 1e-3) return false;  // behind the camera: step rejected
    using Jet3 = ceres::Jet<double, 3>;
    const Jet3 p_jet[3] = {Jet3(p.x(), 0), Jet3(p.y(), 1), Jet3(p.z(), 2)};
    Jet3 uv[2];
    camera_->ProjectT(p_jet, uv);
    residuals[0] = (uv[0].a - u_j_.x()) * inv_sigma_;
    residuals[1] = (uv[1].a - u_j_.y()) * inv_sigma_;
    if (jacobians == nullptr) return true;
    Eigen::Matrix<double, 2, 3> J_p;  // whitened residual by p
    J_p.row(0) = uv[0].v.transpose() * inv_sigma_;
    J_p.row(1) = uv[1].v.transpose() * inv_sigma_;
    // d/d(u, w) of v + 2w (u x v) + 2 u x (u x v):
    //   by u: -2w [v]x + 2 ((u.v) I + u v^T - 2 v u^T),  by w: 2 u x v.
    const auto by_quaternion = [](const Vec3& u, double w, const Vec3& x) {
      Eigen::Matrix<double, 3, 4> J;
      J.leftCols<3>() = -2 * w * Skew(x) + 2 * (u.dot(x) * Mat3::Identity() + u * x.transpose() -
                                                2 * x * u.transpose());
      J.col(3) = 2 * u.cross(x);
      return J;
    };
    const Eigen::Matrix<double, 2, 3> J_d = J_p * Rt_j;  // by d = p_wg - t_j
    using RowMajor2x4 = Eigen::Matrix<double, 2, 4, Eigen::RowMajor>;
    using RowMajor2x3 = Eigen::Matrix<double, 2, 3, Eigen::RowMajor>;
    if (jacobians[0] != nullptr) {
      Eigen::Map<RowMajor2x4> J(jacobians[0]);
      J = J_d * by_quaternion(u_h, w_h, v);
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<RowMajor2x3> J(jacobians[1]);
      J = J_d;
    }
    if (jacobians[2] != nullptr) {
      // The conjugate's u is -u_j: the chain rule flips the u columns.
      Eigen::Matrix<double, 3, 4> J_q = by_quaternion(-u_j, w_j, d);
      J_q.leftCols<3>() *= -1;
      Eigen::Map<RowMajor2x4> J(jacobians[2]);
      J = J_p * J_q;
    }
    if (jacobians[3] != nullptr) {
      Eigen::Map<RowMajor2x3> J(jacobians[3]);
      J = -J_d;
    }
    if (jacobians[4] != nullptr) {
      Eigen::Map<Eigen::Vector2d> J(jacobians[4]);
      J = J_d * (R_h * (-f / (rho * rho)));
    }
    return true;
  }

 private:
  const Camera* camera_;
  Eigen::Vector2d f_h_;
  Eigen::Vector2d u_j_;
  double inv_sigma_;
};

/// Stage 1: LiDAR depth of a map point as a prior on its inverse depth.
/// r = (1/rho - d) / sigma_d, the depth along the host camera's z axis.
struct DepthPriorError {
  DepthPriorError(double depth, double sigma_m) : depth_(depth), inv_sigma_(1.0 / sigma_m) {}

  template <typename T>
  bool operator()(const T* rho, T* residual) const {
    residual[0] = (T(1.0) / rho[0] - T(depth_)) * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(double depth, double sigma_m) {
    return new ceres::AutoDiffCostFunction<DepthPriorError, 1, 1>(
        new DepthPriorError(depth, sigma_m));
  }

 private:
  double depth_;
  double inv_sigma_;
};

/// Stage 1: a map point in inverse-depth form held to the LiDAR map's
/// surface there, plane (n, d) with n.p + d = 0:
///   p_wg = R_h * f_h / rho + t_h,   r = (n . p_wg + d) / sigma.
/// Parameters: q_h, t_h, rho. Unlike a depth prior, this ties the point to
/// the world, so the host pose cannot carry it off the surface.
struct PointToPlaneError {
  PointToPlaneError(const Eigen::Vector2d& f_h, const Eigen::Vector4d& plane, double sigma_m)
      : f_h_(f_h), plane_(plane), inv_sigma_(1.0 / sigma_m) {}

  template <typename T>
  bool operator()(const T* q_h, const T* t_h, const T* rho, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> R_h(q_h);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_h(t_h);
    const Eigen::Matrix<T, 3, 1> f(T(f_h_.x()), T(f_h_.y()), T(1.0));
    const Eigen::Matrix<T, 3, 1> p_wg = R_h * (f / rho[0]) + p_h;
    residual[0] = (plane_.head<3>().template cast<T>().dot(p_wg) + T(plane_[3])) * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector2d& f_h, const Eigen::Vector4d& plane,
                                     double sigma_m) {
    return new ceres::AutoDiffCostFunction<PointToPlaneError, 1, 4, 3, 1>(
        new PointToPlaneError(f_h, plane, sigma_m));
  }

 private:
  Eigen::Vector2d f_h_;
  Eigen::Vector4d plane_;
  double inv_sigma_;
};

/// Relative-motion prior between two 6-DoF poses T_w_a and T_w_b, measured as
/// T_a_b by odometry (LIO for UGV keyframes, VIO for UAV keyframes):
///   dT = T_a_b_measured^-1 * (T_w_a^-1 * T_w_b),
///   r = [ dt / sigma_t ; 2 vec(dq) / sigma_rot ]
/// (as Ceres' pose_graph_3d example, with diagonal sqrt information).
struct RelativePoseError {
  RelativePoseError(const Eigen::Quaterniond& q_ab, const Eigen::Vector3d& t_ab, double sigma_t,
                    double sigma_rot)
      : q_ab_(q_ab), t_ab_(t_ab), inv_sigma_t_(1.0 / sigma_t), inv_sigma_rot_(1.0 / sigma_rot) {}

  template <typename T>
  bool operator()(const T* q_a_ptr, const T* t_a_ptr, const T* q_b_ptr, const T* t_b_ptr,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_a(q_a_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_a(t_a_ptr);
    const Eigen::Map<const Eigen::Quaternion<T>> q_b(q_b_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_b(t_b_ptr);
    const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab_est = q_a_inv * q_b;
    const Eigen::Matrix<T, 3, 1> t_ab_est = q_a_inv * (t_b - t_a);
    const Eigen::Quaternion<T> dq = q_ab_.template cast<T>().conjugate() * q_ab_est;
    const Eigen::Matrix<T, 3, 1> dt = t_ab_est - t_ab_.template cast<T>();
    // Keep the short way round: q and -q are the same rotation.
    const T sign = dq.w() < T(0) ? T(-1) : T(1);
    for (int i = 0; i < 3; ++i) {
      residual[i] = dt[i] * inv_sigma_t_;
      residual[3 + i] = sign * T(2.0) * dq.vec()[i] * inv_sigma_rot_;
    }
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Quaterniond& q_ab, const Eigen::Vector3d& t_ab,
                                     double sigma_t, double sigma_rot) {
    return new ceres::AutoDiffCostFunction<RelativePoseError, 6, 4, 3, 4, 3>(
        new RelativePoseError(q_ab, t_ab, sigma_t, sigma_rot));
  }

 private:
  Eigen::Quaterniond q_ab_;
  Eigen::Vector3d t_ab_;
  double inv_sigma_t_;
  double inv_sigma_rot_;
};

/// Prior of a 6-DoF pose towards a measured value (same residual as
/// RelativePoseError with T_w_a = identity).
struct PosePriorError {
  PosePriorError(const Eigen::Quaterniond& q, const Eigen::Vector3d& t, double sigma_t,
                 double sigma_rot)
      : q_(q), t_(t), inv_sigma_t_(1.0 / sigma_t), inv_sigma_rot_(1.0 / sigma_rot) {}

  template <typename T>
  bool operator()(const T* q_ptr, const T* t_ptr, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(t_ptr);
    const Eigen::Quaternion<T> dq = q_.template cast<T>().conjugate() * q;
    const T sign = dq.w() < T(0) ? T(-1) : T(1);
    for (int i = 0; i < 3; ++i) {
      residual[i] = (t[i] - T(t_[i])) * inv_sigma_t_;
      residual[3 + i] = sign * T(2.0) * dq.vec()[i] * inv_sigma_rot_;
    }
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Quaterniond& q, const Eigen::Vector3d& t,
                                     double sigma_t, double sigma_rot) {
    return new ceres::AutoDiffCostFunction<PosePriorError, 6, 4, 3>(
        new PosePriorError(q, t, sigma_t, sigma_rot));
  }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
  double inv_sigma_t_;
  double inv_sigma_rot_;
};

/// The 4-DoF transform (x, y, z, yaw) applied to a point: RotZ(yaw) p + t.
template <typename T>
Eigen::Matrix<T, 3, 1> ApplyFourDof(const T* x, const Eigen::Matrix<T, 3, 1>& p) {
  using std::cos;
  using std::sin;
  const T c = cos(x[3]);
  const T s = sin(x[3]);
  return Eigen::Matrix<T, 3, 1>(c * p.x() - s * p.y() + x[0], s * p.x() + c * p.y() + x[1],
                                p.z() + x[2]);
}

/// Stage 2, eq. (agreproj): air-ground reprojection. A ground point p_wg
/// (fixed after stage 1) seen by the UAV at pixel u_a:
///   p_ca = R_a^T (T_wa_wg(x) p_wg - t_a),   r = (K_a(p_ca) - u_a) / sigma_px.
/// Parameters: x = (x, y, z, yaw) of T_wa_wg, q_a, t_a of T_wa_ca.
struct AirGroundReprojectionError {
  AirGroundReprojectionError(const Camera* camera, const Eigen::Vector3d& p_wg,
                             const Eigen::Vector2d& u_a, double sigma_px)
      : camera_(camera), p_wg_(p_wg), u_a_(u_a), inv_sigma_(1.0 / sigma_px) {}

  template <typename T>
  bool operator()(const T* x, const T* q_a, const T* t_a, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> R_a(q_a);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(t_a);
    const Eigen::Matrix<T, 3, 1> p_wa = ApplyFourDof(x, p_wg_.cast<T>().eval());
    const Eigen::Matrix<T, 3, 1> p_ca = R_a.conjugate() * (p_wa - p_a);
    if (p_ca.z() <= T(1e-3)) return false;
    T uv[2];
    camera_->ProjectT(p_ca.data(), uv);
    residual[0] = (uv[0] - T(u_a_.x())) * inv_sigma_;
    residual[1] = (uv[1] - T(u_a_.y())) * inv_sigma_;
    return true;
  }

  static ceres::CostFunction* Create(const Camera* camera, const Eigen::Vector3d& p_wg,
                                     const Eigen::Vector2d& u_a, double sigma_px) {
    return new ceres::AutoDiffCostFunction<AirGroundReprojectionError, 2, 4, 4, 3>(
        new AirGroundReprojectionError(camera, p_wg, u_a, sigma_px));
  }

 private:
  const Camera* camera_;
  Eigen::Vector3d p_wg_;
  Eigen::Vector2d u_a_;
  double inv_sigma_;
};

/// Stage 2, eq. (gcon): relative-pose consistency. Each air-ground keyframe
/// pair j gives its own estimate T^_j = T_wa_ca(j) * T_ca_wg(j), where
/// T_ca_wg(j) is that pair's PnP result (fixed) and T_wa_ca(j) the UAV pose
/// being optimised. The paper's || T_wa_wg T^_j^-1 - I || is taken on the
/// 4 DoF: with D = T_wa_wg T^_j^-1,
///   r = [ t_D / sigma_t ; wrap(yaw - yaw^_j) / sigma_yaw ].
/// Parameters: x = (x, y, z, yaw) of T_wa_wg, q_a, t_a.
struct RelativePoseConsistencyError {
  RelativePoseConsistencyError(const Eigen::Quaterniond& q_ca_wg, const Eigen::Vector3d& t_ca_wg,
                               double sigma_t, double sigma_yaw)
      : q_ca_wg_(q_ca_wg),
        t_ca_wg_(t_ca_wg),
        inv_sigma_t_(1.0 / sigma_t),
        inv_sigma_yaw_(1.0 / sigma_yaw) {}

  template <typename T>
  bool operator()(const T* x, const T* q_a, const T* t_a, T* residual) const {
    using std::atan2;
    using std::cos;
    using std::sin;
    const Eigen::Map<const Eigen::Quaternion<T>> R_a(q_a);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(t_a);
    // T^ = T_wa_ca * T_ca_wg
    const Eigen::Quaternion<T> q_hat = R_a * q_ca_wg_.cast<T>();
    const Eigen::Matrix<T, 3, 1> t_hat = R_a * t_ca_wg_.cast<T>() + p_a;
    const Eigen::Matrix<T, 3, 3> R_hat = q_hat.toRotationMatrix();
    // Yaw of T^ projected to a rotation about z (closest in Frobenius norm).
    const T yaw_hat = atan2(R_hat(1, 0) - R_hat(0, 1), R_hat(0, 0) + R_hat(1, 1));
    const T d_yaw = x[3] - yaw_hat;
    // t_D = t - RotZ(yaw - yaw^) t^
    const T c = cos(d_yaw);
    const T s = sin(d_yaw);
    residual[0] = (x[0] - (c * t_hat.x() - s * t_hat.y())) * inv_sigma_t_;
    residual[1] = (x[1] - (s * t_hat.x() + c * t_hat.y())) * inv_sigma_t_;
    residual[2] = (x[2] - t_hat.z()) * inv_sigma_t_;
    residual[3] = atan2(s, c) * inv_sigma_yaw_;
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Quaterniond& q_ca_wg,
                                     const Eigen::Vector3d& t_ca_wg, double sigma_t,
                                     double sigma_yaw) {
    return new ceres::AutoDiffCostFunction<RelativePoseConsistencyError, 4, 4, 4, 3>(
        new RelativePoseConsistencyError(q_ca_wg, t_ca_wg, sigma_t, sigma_yaw));
  }

 private:
  Eigen::Quaterniond q_ca_wg_;
  Eigen::Vector3d t_ca_wg_;
  double inv_sigma_t_;
  double inv_sigma_yaw_;
};

/// Stage 1's run-long camera rotation (camera_rotation.h): a keypoint's ray
/// in its host keyframe h, with the camera rotation correction R_d (angle-
/// axis d, applied on the right of both LIO camera poses), is cut with the
/// map plane (n, d0) and reprojected into the observing keyframe o:
///   r_h = R_h R_d f_h,   s = -(n.t_h + d0) / (n.r_h),   p = t_h + s r_h,
///   x_o = R_d^T R_o^T (p - t_o),
///   r = (x_o[0:2] / x_o[2] - f_o) * focal / sigma_px.
/// A wrong rotation moves the cut along the plane (far, at grazing rays),
/// so the reprojection in o misses its match. With a time offset dt each
/// LIO pose is first moved along the camera's motion, to first order:
/// R -> R Exp(omega_c dt), t -> t + v_wg dt. Parameters: d (3), dt (1).
/// The calibrator uses PlaneCutReprojectionCost below (the same residual,
/// analytic Jacobians); this autodiff form is the reference the tests and
/// stage1_bench hold it to.
struct PlaneCutReprojectionError {
  PlaneCutReprojectionError(const PlaneTrackObservation& o, double scale) : o_(o), scale_(scale) {}

  /// d: the rotation correction (angle-axis, camera frame); dt: the time
  /// offset (s), moving each camera along its motion (omega_c, v_wg).
  template <typename T>
  bool operator()(const T* d, const T* dt, T* residual) const {
    using V = Eigen::Matrix<T, 3, 1>;
    // Camera pose at t + dt, to first order, then the correction.
    auto rotate = [&](const Eigen::Vector3d& omega, const T* angle_axis_d, const V& x) {
      const V w = omega.cast<T>() * dt[0];
      V y, z;
      ceres::AngleAxisRotatePoint(angle_axis_d, x.data(), y.data());
      ceres::AngleAxisRotatePoint(w.data(), y.data(), z.data());
      return z;
    };
    const V f(T(o_.f_host.x()), T(o_.f_host.y()), T(1.0));
    const V ray = o_.T_wg_c_host.linear().cast<T>() * rotate(o_.omega_host_c, d, f);
    const V t_h = o_.T_wg_c_host.translation().cast<T>() + o_.v_host_wg.cast<T>() * dt[0];
    const V n = o_.plane.head<3>().cast<T>();
    const T denom = n.dot(ray);
    const T s = -(n.dot(t_h) + T(o_.plane[3])) / denom;
    if (!(s > T(0.1))) return false;  // cut behind the camera: step rejected
    const V p = t_h + s * ray;
    const V t_o = o_.T_wg_c_obs.translation().cast<T>() + o_.v_obs_wg.cast<T>() * dt[0];
    const V x_lio = o_.T_wg_c_obs.linear().transpose().cast<T>() * (p - t_o);
    // The inverse of rotate(): undo the motion, then the correction.
    const V w_inv = -o_.omega_obs_c.cast<T>() * dt[0];
    const T minus_d[3] = {-d[0], -d[1], -d[2]};
    V y, x;
    ceres::AngleAxisRotatePoint(w_inv.data(), x_lio.data(), y.data());
    ceres::AngleAxisRotatePoint(minus_d, y.data(), x.data());
    if (!(x.z() > T(1e-3))) return false;
    residual[0] = (x.x() / x.z() - T(o_.f_obs.x())) * T(scale_);
    residual[1] = (x.y() / x.z() - T(o_.f_obs.y())) * T(scale_);
    return true;
  }

  static ceres::CostFunction* Create(const PlaneTrackObservation& o, double scale) {
    return new ceres::AutoDiffCostFunction<PlaneCutReprojectionError, 2, 3, 1>(
        new PlaneCutReprojectionError(o, scale));
  }

 private:
  PlaneTrackObservation o_;
  double scale_;
};

/// PlaneCutReprojectionError with analytic Jacobians: the calibrator
/// evaluates it over its whole sample (6000 observations) at every
/// iteration, and with 4-wide jets that was two thirds of its solve
/// (stage1_bench). The same residual, parameters and rejected steps; the
/// tests hold it to the autodiff form. An angle-axis rotation phi is
/// differentiated through the left Jacobian of SO(3),
///   d(R(phi) v)/d(phi) = -[R(phi) v]x J_l(phi),
/// and a rotation omega * dt about a fixed axis by dt as omega x (R v).
class PlaneCutReprojectionCost final : public ceres::SizedCostFunction<2, 3, 1> {
 public:
  PlaneCutReprojectionCost(const PlaneTrackObservation& o, double scale)
      : R_h_(o.T_wg_c_host.linear()),
        t_h_(o.T_wg_c_host.translation()),
        Rt_o_(o.T_wg_c_obs.linear().transpose()),
        t_o_(o.T_wg_c_obs.translation()),
        f_host_(o.f_host.x(), o.f_host.y(), 1.0),
        f_obs_(o.f_obs),
        n_(o.plane.head<3>()),
        plane_d_(o.plane[3]),
        omega_h_(o.omega_host_c),
        v_h_(o.v_host_wg),
        omega_o_(o.omega_obs_c),
        v_o_(o.v_obs_wg),
        scale_(scale) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    using Mat3 = Eigen::Matrix3d;
    using Vec3 = Eigen::Vector3d;
    const Eigen::Map<const Vec3> d(parameters[0]);
    const double dt = parameters[1][0];
    const Mat3 R_d = AngleAxisMatrix(d);
    const Mat3 R_wh = AngleAxisMatrix(omega_h_ * dt);
    const Mat3 R_wo = AngleAxisMatrix(-omega_o_ * dt);
    const Vec3 a = R_d * f_host_;
    const Vec3 b = R_wh * a;
    const Vec3 ray = R_h_ * b;
    const Vec3 t_h = t_h_ + v_h_ * dt;
    const double denom = n_.dot(ray);
    const double s = -(n_.dot(t_h) + plane_d_) / denom;
    if (!(s > 0.1)) return false;  // cut behind the camera: step rejected
    const Vec3 p = t_h + s * ray;
    const Mat3 to_obs = R_wo * Rt_o_;
    const Vec3 y = to_obs * (p - t_o_ - v_o_ * dt);
    const Vec3 x = R_d.transpose() * y;
    if (!(x.z() > 1e-3)) return false;
    residuals[0] = (x.x() / x.z() - f_obs_.x()) * scale_;
    residuals[1] = (x.y() / x.z() - f_obs_.y()) * scale_;
    if (jacobians == nullptr) return true;
    const double iz = 1.0 / x.z();
    Eigen::Matrix<double, 2, 3> J_x;  // whitened residual by x
    J_x << iz, 0, -x.x() * iz * iz, 0, iz, -x.y() * iz * iz;
    J_x *= scale_;
    // Host ray and cut; then into the observing camera; d enters twice.
    const Mat3 J_l = LeftJacobian(d);  // J_l(-d) = J_l(d)^T
    const Mat3 ray_d = R_h_ * R_wh * (-Skew(a) * J_l);
    const Vec3 ray_dt = R_h_ * omega_h_.cross(b);
    const Eigen::RowVector3d s_d = -(s / denom) * (n_.transpose() * ray_d);
    const double s_dt = -(n_.dot(v_h_) + s * n_.dot(ray_dt)) / denom;
    const Mat3 p_d = ray * s_d + s * ray_d;
    const Vec3 p_dt = v_h_ + ray * s_dt + s * ray_dt;
    const Mat3 x_d = R_d.transpose() * (to_obs * p_d) + Skew(x) * J_l.transpose();
    const Vec3 x_dt = R_d.transpose() * ((-omega_o_).cross(y) + to_obs * (p_dt - v_o_));
    if (jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> J(jacobians[0]);
      J = J_x * x_d;
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Vector2d> J(jacobians[1]);
      J = J_x * x_dt;
    }
    return true;
  }

 private:
  /// As ceres::AngleAxisRotatePoint rotates: first order below machine
  /// epsilon in the squared angle.
  static Eigen::Matrix3d AngleAxisMatrix(const Eigen::Vector3d& phi) {
    const double theta2 = phi.squaredNorm();
    if (theta2 > std::numeric_limits<double>::epsilon()) {
      const double theta = std::sqrt(theta2);
      return Eigen::AngleAxisd(theta, phi / theta).toRotationMatrix();
    }
    return Eigen::Matrix3d::Identity() + Skew(phi);
  }
  /// J_l(phi) = I + (1 - cos t) / t^2 [phi]x + (t - sin t) / t^3 [phi]x^2,
  /// by its series where those quotients lose digits.
  static Eigen::Matrix3d LeftJacobian(const Eigen::Vector3d& phi) {
    const double theta2 = phi.squaredNorm();
    double a, b;
    if (theta2 < 1e-8) {
      a = 0.5 - theta2 / 24;
      b = 1.0 / 6 - theta2 / 120;
    } else {
      const double theta = std::sqrt(theta2);
      a = (1 - std::cos(theta)) / theta2;
      b = (theta - std::sin(theta)) / (theta2 * theta);
    }
    const Eigen::Matrix3d S = Skew(phi);
    return Eigen::Matrix3d::Identity() + a * S + b * S * S;
  }

  Eigen::Matrix3d R_h_;
  Eigen::Vector3d t_h_;
  Eigen::Matrix3d Rt_o_;
  Eigen::Vector3d t_o_, f_host_;
  Eigen::Vector2d f_obs_;
  Eigen::Vector3d n_;
  double plane_d_;
  Eigen::Vector3d omega_h_, v_h_, omega_o_, v_o_;
  double scale_;
};

}  // namespace ag
