#include "ground_server/estimation/camera_rotation.h"

#include <ceres/normal_prior.h>
#include <ceres/rotation.h>

#include <array>
#include <cmath>

#include "ground_server/estimation/cost_functions.h"

namespace ag {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

/// Prior of the correction towards zero (the nominal extrinsic).
struct RotationPriorError {
  explicit RotationPriorError(double sigma_rad) : inv_sigma(1.0 / sigma_rad) {}
  template <typename T>
  bool operator()(const T* d, T* residual) const {
    for (int i = 0; i < 3; ++i) residual[i] = d[i] * T(inv_sigma);
    return true;
  }
  double inv_sigma;
};

bool AllFinite(const PlaneTrackObservation& o) {
  return o.T_wg_c_host.matrix().allFinite() && o.T_wg_c_obs.matrix().allFinite() &&
         o.f_host.allFinite() && o.f_obs.allFinite() && o.plane.allFinite() &&
         o.omega_host_c.allFinite() && o.v_host_wg.allFinite() && o.omega_obs_c.allFinite() &&
         o.v_obs_wg.allFinite() && std::isfinite(o.focal_px) && o.focal_px > 0;
}

}  // namespace

void CameraRotationCalibrator::Options::Check() const {
  CheckOption(max_observations >= 1, "max_observations", "must be >= 1");
  CheckOption(min_observations >= 1, "min_observations", "must be >= 1");
  CheckOption(sigma_px > 0, "sigma_px", "must be > 0");
  CheckOption(prior_sigma_deg > 0, "prior_sigma_deg", "must be > 0");
  CheckOption(min_ray_plane_angle_deg >= 0 && min_ray_plane_angle_deg < 90,
              "min_ray_plane_angle_deg", "must be in [0, 90)");
  CheckOption(time_offset_prior_sigma_s > 0, "time_offset_prior_sigma_s", "must be > 0");
  CheckOption(max_iterations > 0, "max_iterations", "must be > 0");
  CheckOption(resolve_fraction >= 0 && resolve_fraction <= 1, "resolve_fraction",
              "must be in [0, 1]");
  loss.Check();
}

CameraRotationCalibrator::CameraRotationCalibrator(const Options& options) : options_(options) {
  options_.Check();
}

bool CameraRotationCalibrator::Add(const std::tuple<int64_t, int, int64_t>& key,
                                   const PlaneTrackObservation& obs) {
  if (!AllFinite(obs) || keys_.count(key)) return false;
  const Eigen::Vector3d n = obs.plane.head<3>();
  if (std::abs(n.norm() - 1.0) > 1e-3) return false;
  const Eigen::Vector3d ray =
      obs.T_wg_c_host.linear() * Eigen::Vector3d(obs.f_host.x(), obs.f_host.y(), 1.0).normalized();
  if (std::abs(n.dot(ray)) < std::sin(options_.min_ray_plane_angle_deg * kDegToRad)) return false;
  keys_.insert(key);
  recent_keys_.push_back(key);
  if (static_cast<int>(recent_keys_.size()) > 4 * options_.max_observations) {
    keys_.erase(recent_keys_.front());
    recent_keys_.pop_front();
  }
  ++added_since_solve_;
  ++offered_;
  // Reservoir sampling (Vitter's algorithm R): the kept observations are a
  // uniform sample of every one offered so far.
  if (static_cast<int>(observations_.size()) < options_.max_observations) {
    observations_.push_back(obs);
  } else {
    const uint64_t j = std::uniform_int_distribution<uint64_t>(0, offered_ - 1)(rng_);
    if (j < observations_.size()) observations_[j] = obs;
  }
  return true;
}

CameraRotationCalibrator::SolveResult CameraRotationCalibrator::Solve() {
  SolveResult result;
  result.observations = num_observations();
  if (result.observations < options_.min_observations) {
    result.reason = std::to_string(result.observations) + " plane-track observations, need " +
                    std::to_string(options_.min_observations);
    return result;
  }
  if (has_estimate_ &&
      added_since_solve_ < options_.resolve_fraction * static_cast<double>(offered_)) {
    result.reason = "too few new observations since the last solve";
    return result;
  }
  added_since_solve_ = 0;
  std::array<double, 3> d = {angle_axis_.x(), angle_axis_.y(), angle_axis_.z()};
  double dt = time_offset_s_;
  ceres::Problem problem;
  int used = 0;
  for (const PlaneTrackObservation& o : observations_) {
    problem.AddResidualBlock(new PlaneCutReprojectionCost(o, o.focal_px / options_.sigma_px),
                             MakeLoss(options_.loss), d.data(), &dt);
    ++used;
  }
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<RotationPriorError, 3, 3>(
                               new RotationPriorError(options_.prior_sigma_deg * kDegToRad)),
                           nullptr, d.data());
  if (options_.estimate_time_offset) {
    const Eigen::Matrix<double, 1, 1> a(1.0 / options_.time_offset_prior_sigma_s);
    problem.AddResidualBlock(new ceres::NormalPrior(a, Eigen::Matrix<double, 1, 1>::Zero()),
                             nullptr, &dt);
  } else {
    problem.SetParameterBlockConstant(&dt);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options_.max_iterations;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  const double n_res = 2.0 * used;
  result.initial_rms_px = std::sqrt(2.0 * summary.initial_cost / n_res) * options_.sigma_px;
  result.final_rms_px = std::sqrt(2.0 * summary.final_cost / n_res) * options_.sigma_px;
  const Eigen::Vector3d solved(d[0], d[1], d[2]);
  if (!summary.IsSolutionUsable() || !solved.allFinite() || !std::isfinite(dt)) {
    result.reason = "solver: " + summary.message;
    return result;
  }
  angle_axis_ = solved;
  time_offset_s_ = dt;
  const double angle = solved.norm();
  rotation_ = angle > 0 ? Eigen::AngleAxisd(angle, solved / angle).toRotationMatrix()
                        : Eigen::Matrix3d::Identity();
  has_estimate_ = true;
  result.updated = true;
  return result;
}

}  // namespace ag
