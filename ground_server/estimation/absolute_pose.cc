#include "ground_server/estimation/absolute_pose.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <random>

#include "common/core/error.h"

namespace ag {
namespace {

// Rows of (q - c) x b = C * D * y for y = (cos, sin, tx, ty, tz, 1).
Eigen::Matrix<double, 3, 6> ConstraintRows(const RayPointCorrespondence& k) {
  const Eigen::Vector3d& p = k.p_wg;
  const Eigen::Vector3d& c = k.c_wa;
  const Eigen::Vector3d& b = k.b_wa;
  Eigen::Matrix<double, 3, 6> D;
  D << p.x(), -p.y(), 1, 0, 0, -c.x(),  //
      p.y(), p.x(), 0, 1, 0, -c.y(),    //
      0, 0, 0, 0, 1, p.z() - c.z();
  Eigen::Matrix3d C;
  C << 0, b.z(), -b.y(),  //
      -b.z(), 0, b.x(),   //
      b.y(), -b.x(), 0;
  return C * D;
}

// Residual of a correspondence on the normalised image plane of its camera.
bool NormalizedResidual(const Pose& T_wa_wg, const RayPointCorrespondence& k, const Pose& T_wa_ca,
                        Eigen::Vector2d* r) {
  const Eigen::Vector3d p_ca = T_wa_ca.inverse() * (T_wa_wg * k.p_wg);
  if (p_ca.z() <= 1e-6) return false;
  *r = p_ca.head<2>() / p_ca.z() - k.xy_normalized;
  return true;
}

}  // namespace

void RansacOptions::Check() const {
  CheckOption(solver == "four_dof" || solver == "epnp", "solver",
              "must be 'four_dof' or 'epnp', got '" + solver + "'");
  CheckOption(inlier_threshold_px > 0, "inlier_threshold_px", "must be > 0");
  CheckOption(max_iterations > 0, "max_iterations", "must be > 0");
  CheckOption(confidence > 0 && confidence < 1, "confidence", "must be in (0, 1)");
  CheckOption(min_inliers >= 3, "min_inliers", "must be >= 3");
}

std::vector<Pose> SolveFourDofMinimal(const RayPointCorrespondence& a,
                                      const RayPointCorrespondence& b) {
  Eigen::Matrix<double, 6, 6> M;
  M.topRows<3>() = ConstraintRows(a);
  M.bottomRows<3>() = ConstraintRows(b);
  const Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>> svd(M, Eigen::ComputeFullV);
  const Eigen::Matrix<double, 6, 1> v1 = svd.matrixV().col(4);
  const Eigen::Matrix<double, 6, 1> v2 = svd.matrixV().col(5);
  // Homogeneous quadratic in (alpha, beta): y1^2 + y2^2 - y6^2 = 0.
  auto quad = [&](int i, int j) { return v1(i) * v2(j) + v2(i) * v1(j); };
  const double qa = v1(0) * v1(0) + v1(1) * v1(1) - v1(5) * v1(5);
  const double qb = quad(0, 0) + quad(1, 1) - quad(5, 5);
  const double qc = v2(0) * v2(0) + v2(1) * v2(1) - v2(5) * v2(5);
  std::vector<std::pair<double, double>> ab;  // (alpha, beta) up to scale
  if (std::abs(qa) > 1e-12) {
    // alpha = r beta: qa r^2 + qb r + qc = 0
    const double disc = qb * qb - 4 * qa * qc;
    if (disc < 0) return {};
    const double s = std::sqrt(disc);
    ab.emplace_back((-qb + s) / (2 * qa), 1.0);
    if (s > 0) ab.emplace_back((-qb - s) / (2 * qa), 1.0);
  } else {
    // qb alpha beta + qc beta^2 = 0: beta = 0, or alpha = -qc / qb beta.
    ab.emplace_back(1.0, 0.0);
    if (std::abs(qb) > 1e-12) ab.emplace_back(-qc / qb, 1.0);
  }
  std::vector<Pose> solutions;
  for (const auto& [alpha, beta] : ab) {
    Eigen::Matrix<double, 6, 1> y = alpha * v1 + beta * v2;
    if (std::abs(y(5)) < 1e-12) continue;
    y /= y(5);
    const double yaw = std::atan2(y(1), y(0));
    const Pose T = MakePose4Dof(y(2), y(3), y(4), yaw);
    if (!T.matrix().allFinite()) continue;
    // Cheirality: both points in front along their rays.
    if ((T * a.p_wg - a.c_wa).dot(a.b_wa) <= 0 || (T * b.p_wg - b.c_wa).dot(b.b_wa) <= 0) continue;
    solutions.push_back(T);
  }
  return solutions;
}

double AngularError(const Pose& T_wa_wg, const RayPointCorrespondence& c) {
  const Eigen::Vector3d d = T_wa_wg * c.p_wg - c.c_wa;
  const double along = d.dot(c.b_wa);
  if (along <= 0) return std::numeric_limits<double>::infinity();
  return std::atan2(d.cross(c.b_wa).norm(), along);
}

Pose RefineFourDof(const Pose& T_wa_wg, const std::vector<RayPointCorrespondence>& correspondences,
                   const std::vector<int>& indices, const std::vector<Pose>& T_wa_ca,
                   int iterations) {
  Eigen::Vector4d x(T_wa_wg.translation().x(), T_wa_wg.translation().y(), T_wa_wg.translation().z(),
                    ProjectedYaw(T_wa_wg.linear()));
  auto pose_of = [](const Eigen::Vector4d& v) { return MakePose4Dof(v(0), v(1), v(2), v(3)); };
  for (int it = 0; it < iterations; ++it) {
    Eigen::Matrix4d H = Eigen::Matrix4d::Zero();
    Eigen::Vector4d g = Eigen::Vector4d::Zero();
    const Pose T0 = pose_of(x);
    for (int i : indices) {
      const RayPointCorrespondence& k = correspondences[i];
      Eigen::Vector2d r0;
      if (!NormalizedResidual(T0, k, T_wa_ca[k.air_frame], &r0)) continue;
      Eigen::Matrix<double, 2, 4> J;
      bool ok = true;
      for (int d = 0; d < 4 && ok; ++d) {
        const double h = d < 3 ? 1e-6 : 1e-7;
        Eigen::Vector4d xp = x, xm = x;
        xp(d) += h;
        xm(d) -= h;
        Eigen::Vector2d rp, rm;
        ok = NormalizedResidual(pose_of(xp), k, T_wa_ca[k.air_frame], &rp) &&
             NormalizedResidual(pose_of(xm), k, T_wa_ca[k.air_frame], &rm);
        J.col(d) = (rp - rm) / (2 * h);
      }
      if (!ok) continue;
      H += J.transpose() * J;
      g += J.transpose() * r0;
    }
    const Eigen::Vector4d dx = H.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    x += dx;
    if (dx.head<3>().norm() < 1e-9 && std::abs(dx(3)) < 1e-10) break;
  }
  return pose_of(x);
}

namespace {

std::vector<int> Inliers(const Pose& T, const std::vector<RayPointCorrespondence>& corr,
                         double threshold_rad, double* total_error) {
  std::vector<int> inliers;
  double total = 0;
  for (size_t i = 0; i < corr.size(); ++i) {
    const double e = AngularError(T, corr[i]);
    if (e < threshold_rad) {
      inliers.push_back(static_cast<int>(i));
      total += e;
    } else {
      total += threshold_rad;  // MSAC-style truncated cost breaks ties
    }
  }
  if (total_error) *total_error = total;
  return inliers;
}

int RequiredIterations(double inlier_ratio, int sample_size, double confidence, int cap) {
  const double w = std::pow(inlier_ratio, sample_size);
  if (w <= 1e-12) return cap;
  if (w >= 1.0 - 1e-12) return 1;
  const double n = std::log(1.0 - confidence) / std::log(1.0 - w);
  return static_cast<int>(std::min<double>(cap, std::ceil(n)));
}

struct Hypothesis {
  Pose T = Pose::Identity();
  std::vector<int> inliers;
  double cost = std::numeric_limits<double>::infinity();
};

void Consider(const Pose& T, const std::vector<RayPointCorrespondence>& corr, double thr,
              Hypothesis* best) {
  double cost = 0;
  std::vector<int> inliers = Inliers(T, corr, thr, &cost);
  if (cost < best->cost) {
    best->T = T;
    best->inliers = std::move(inliers);
    best->cost = cost;
  }
}

}  // namespace

AbsolutePoseResult EstimateAbsolutePose(const std::vector<RayPointCorrespondence>& correspondences,
                                        const std::vector<Pose>& T_wa_ca, double focal_px,
                                        const RansacOptions& options) {
  AbsolutePoseResult result;
  const int n = static_cast<int>(correspondences.size());
  if (n < options.min_inliers) {
    result.reason = "only " + std::to_string(n) + " correspondences (need " +
                    std::to_string(options.min_inliers) + ")";
    return result;
  }
  const double thr = options.inlier_threshold_px / focal_px;
  Hypothesis best;
  std::mt19937_64 rng(options.seed);
  if (options.solver == "four_dof") {
    std::uniform_int_distribution<int> pick(0, n - 1);
    int needed = options.max_iterations;
    int it = 0;
    for (; it < needed; ++it) {
      const int i = pick(rng);
      int j = pick(rng);
      if (j == i) j = (j + 1) % n;
      for (const Pose& T : SolveFourDofMinimal(correspondences[i], correspondences[j])) {
        const size_t before = best.inliers.size();
        Consider(T, correspondences, thr, &best);
        if (best.inliers.size() > before) {
          needed =
              std::max(it + 1, RequiredIterations(static_cast<double>(best.inliers.size()) / n, 2,
                                                  options.confidence, options.max_iterations));
        }
      }
    }
    result.iterations = it;
  } else {
    // EPnP + RANSAC per UAV frame on normalised coordinates (K = I).
    int frames = 0;
    for (const auto& k : correspondences) frames = std::max(frames, k.air_frame + 1);
    for (int f = 0; f < frames; ++f) {
      std::vector<cv::Point3d> object;
      std::vector<cv::Point2d> image;
      for (const auto& k : correspondences) {
        if (k.air_frame != f) continue;
        object.emplace_back(k.p_wg.x(), k.p_wg.y(), k.p_wg.z());
        image.emplace_back(k.xy_normalized.x(), k.xy_normalized.y());
      }
      if (static_cast<int>(object.size()) < std::max(options.min_inliers, 6)) continue;
      cv::Mat rvec, tvec;
      std::vector<int> pnp_inliers;
      cv::setRNGSeed(static_cast<int>(options.seed));
      const bool ok = cv::solvePnPRansac(object, image, cv::Mat::eye(3, 3, CV_64F), cv::noArray(),
                                         rvec, tvec, false, options.max_iterations, thr,
                                         options.confidence, pnp_inliers, cv::SOLVEPNP_EPNP);
      result.iterations += options.max_iterations;
      if (!ok) continue;
      cv::Mat R_cv;
      cv::Rodrigues(rvec, R_cv);
      Eigen::Matrix3d R;
      Eigen::Vector3d t;
      cv::cv2eigen(R_cv, R);
      cv::cv2eigen(tvec, t);
      Pose T_ca_wg = Pose::Identity();
      T_ca_wg.linear() = R;
      T_ca_wg.translation() = t;
      Consider(ProjectTo4Dof(T_wa_ca[f] * T_ca_wg), correspondences, thr, &best);
    }
  }
  if (static_cast<int>(best.inliers.size()) < options.min_inliers) {
    result.reason = "RANSAC found " + std::to_string(best.inliers.size()) + " inliers (need " +
                    std::to_string(options.min_inliers) + ")";
    return result;
  }
  // Least-squares polish on the inliers, then re-collect them once.
  Pose T = RefineFourDof(best.T, correspondences, best.inliers, T_wa_ca);
  std::vector<int> inliers = Inliers(T, correspondences, thr, nullptr);
  if (inliers.size() >= best.inliers.size()) {
    T = RefineFourDof(T, correspondences, inliers, T_wa_ca);
  } else {
    T = best.T;
    inliers = best.inliers;
  }
  result.success = true;
  result.T_wa_wg = T;
  result.inliers = std::move(inliers);
  return result;
}

}  // namespace ag
