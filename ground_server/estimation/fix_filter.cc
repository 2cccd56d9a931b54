#include "ground_server/estimation/fix_filter.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "common/core/error.h"

namespace ag {
namespace {

Eigen::Vector4d ToVector(const Pose& T) {
  Eigen::Vector4d x;
  x << T.translation(), ProjectedYaw(T.linear());
  return x;
}

}  // namespace

void FixFilter::Options::Check() const {
  CheckOption(std::isfinite(drift_translation_m) && drift_translation_m >= 0, "drift_translation_m",
              "must be >= 0");
  CheckOption(std::isfinite(drift_yaw_deg) && drift_yaw_deg >= 0, "drift_yaw_deg", "must be >= 0");
  CheckOption(weight > 0 && weight <= 1, "weight", "must be in (0, 1]");
}

FixFilter::FixFilter(const Options& options) : options_(options) { options_.Check(); }

void FixFilter::Reset(int64_t t_ns, const Pose& T_wa_wg, const Eigen::Matrix4d& covariance,
                      int64_t air_t_ns) {
  t_ns_ = t_ns;
  air_t_ns_ = air_t_ns;
  x_ = ToVector(T_wa_wg);
  P_ = covariance;
}

void FixFilter::Update(int64_t t_ns, const Pose& T_wa_wg, const Eigen::Matrix4d& covariance,
                       int64_t air_t_ns) {
  if (!options_.enabled || !t_ns_ || t_ns <= *t_ns_) {
    Reset(t_ns, T_wa_wg, covariance, air_t_ns);
    return;
  }
  // Predict: the relation drifts as a random walk, over both agents' time.
  const double dt = 1e-9 * (static_cast<double>(t_ns - *t_ns_) +
                            std::abs(static_cast<double>(air_t_ns - air_t_ns_)));
  const double q_t = options_.drift_translation_m * options_.drift_translation_m * dt;
  const double q_yaw = std::pow(options_.drift_yaw_deg * M_PI / 180, 2) * dt;
  P_.diagonal() += Eigen::Vector4d(q_t, q_t, q_t, q_yaw);
  // Update with the estimate, its covariance scaled for the data it shares
  // with the previous ones.
  const Eigen::Matrix4d R = covariance / options_.weight;
  Eigen::Vector4d innovation = ToVector(T_wa_wg) - x_;
  innovation[3] = WrapAngle(innovation[3]);
  const Eigen::Matrix4d S = P_ + R;
  const Eigen::LDLT<Eigen::Matrix4d> ldlt(S);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) {
    Reset(t_ns, T_wa_wg, covariance, air_t_ns);
    return;
  }
  const Eigen::Matrix4d K = ldlt.solve(P_).transpose();  // P S^-1 (both symmetric)
  x_ += K * innovation;
  x_[3] = WrapAngle(x_[3]);
  // Joseph form: stays symmetric positive definite.
  const Eigen::Matrix4d I_K = Eigen::Matrix4d::Identity() - K;
  P_ = I_K * P_ * I_K.transpose() + K * R * K.transpose();
  t_ns_ = t_ns;
  air_t_ns_ = air_t_ns;
}

Pose FixFilter::T_wa_wg() const { return MakePose4Dof(x_[0], x_[1], x_[2], x_[3]); }

}  // namespace ag
