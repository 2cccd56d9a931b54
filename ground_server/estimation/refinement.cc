#include "ground_server/estimation/refinement.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "common/core/error.h"
#include "ground_server/estimation/cost_functions.h"

namespace ag {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// A 6-DoF pose as the two parameter blocks the cost functions use.
struct PoseBlock {
  std::array<double, 4> q;  // Eigen order x, y, z, w
  std::array<double, 3> t;

  explicit PoseBlock(const Pose& T) {
    const Eigen::Quaterniond qe(T.linear());
    q = {qe.x(), qe.y(), qe.z(), qe.w()};
    t = {T.translation().x(), T.translation().y(), T.translation().z()};
  }
  Pose ToPose() const {
    Pose T = Pose::Identity();
    T.linear() = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    return T;
  }
  void AddTo(ceres::Problem* problem) {
    problem->AddParameterBlock(q.data(), 4, new ceres::EigenQuaternionManifold());
    problem->AddParameterBlock(t.data(), 3);
  }
  void SetConstant(ceres::Problem* problem) {
    problem->SetParameterBlockConstant(q.data());
    problem->SetParameterBlockConstant(t.data());
  }
};

ceres::Solver::Options SolverOptions(int max_iterations) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_SCHUR;
  o.max_num_iterations = max_iterations;
  o.num_threads = 1;
  o.minimizer_progress_to_stdout = false;
  o.logging_type = ceres::SILENT;
  return o;
}

}  // namespace

void RobustLossOptions::Check() const {
  CheckOption(type == "huber" || type == "cauchy" || type == "none", "type",
              "must be huber, cauchy or none; got '" + type + "'");
  CheckOption(scale > 0, "scale", "must be > 0");
}

void Stage1Options::Check() const {
  CheckOption(sigma_px > 0, "sigma_px", "must be > 0");
  CheckOption(depth_sigma_m > 0, "depth_sigma_m", "must be > 0");
  CheckOption(lio_sigma_t_m > 0, "lio_sigma_t_m", "must be > 0");
  CheckOption(lio_sigma_rot_deg > 0, "lio_sigma_rot_deg", "must be > 0");
  CheckOption(plane_sigma_m > 0, "plane_sigma_m", "must be > 0");
  CheckOption(min_plane_tracks >= 3, "min_plane_tracks", "must be >= 3");
  CheckOption(pose_prior_sigma_t_m > 0, "pose_prior_sigma_t_m", "must be > 0");
  CheckOption(pose_prior_sigma_rot_deg > 0, "pose_prior_sigma_rot_deg", "must be > 0");
  CheckOption(max_iterations > 0, "max_iterations", "must be > 0");
}

void Stage2Options::Check() const {
  CheckOption(use_reprojection || use_consistency, "use_reprojection",
              "and use_consistency are both off: stage 2 would have no measurement");
  CheckOption(sigma_px > 0, "sigma_px", "must be > 0");
  CheckOption(consistency_sigma_t_m > 0, "consistency_sigma_t_m", "must be > 0");
  CheckOption(consistency_sigma_yaw_deg > 0, "consistency_sigma_yaw_deg", "must be > 0");
  CheckOption(vio_sigma_t_per_s >= 0, "vio_sigma_t_per_s", "must be >= 0");
  CheckOption(vio_sigma_rot_deg_per_s >= 0, "vio_sigma_rot_deg_per_s", "must be >= 0");
  CheckOption(vio_sigma_floor_t_m > 0, "vio_sigma_floor_t_m", "must be > 0");
  CheckOption(vio_sigma_floor_rot_deg > 0, "vio_sigma_floor_rot_deg", "must be > 0");
  CheckOption(max_iterations > 0, "max_iterations", "must be > 0");
}

Stage1Result RunStage1(const std::vector<UgvWindowFrame>& frames,
                       const std::vector<UgvTrack>& tracks, const Stage1Options& options) {
  Stage1Result result;
  const int n_frames = static_cast<int>(frames.size());
  if (n_frames < 2) {
    result.reason = "stage 1 needs at least 2 UGV keyframes, got " + std::to_string(n_frames);
    return result;
  }
  ceres::Problem problem;
  std::vector<PoseBlock> poses;
  poses.reserve(frames.size());
  for (const UgvWindowFrame& f : frames) poses.emplace_back(f.T_wg_c);
  for (PoseBlock& p : poses) p.AddTo(&problem);
  std::vector<double> rho(tracks.size());
  auto seen_twice = [&](const UgvTrack& track) {
    for (const auto& obs : track.observations) {
      if (obs.first != track.host_frame && obs.first >= 0 && obs.first < n_frames) return true;
    }
    return false;
  };
  int plane_tracks = 0;
  for (const UgvTrack& track : tracks)
    plane_tracks += (track.has_plane() && seen_twice(track)) ? 1 : 0;
  const bool anchored = options.anchor_to_map && plane_tracks >= options.min_plane_tracks;
  int observations = 0;
  for (size_t k = 0; k < tracks.size(); ++k) {
    const UgvTrack& track = tracks[k];
    rho[k] = 1.0 / track.lidar_depth;
    if (!seen_twice(track)) continue;
    PoseBlock& h = poses[track.host_frame];
    for (const auto& [j, uv] : track.observations) {
      if (j == track.host_frame || j < 0 || j >= n_frames) continue;
      PoseBlock& target = poses[j];
      problem.AddResidualBlock(
          new InverseDepthReprojectionCost(frames[j].camera, track.f_host, uv, options.sigma_px),
          MakeLoss(options.loss), h.q.data(), h.t.data(), target.q.data(), target.t.data(),
          &rho[k]);
      ++observations;
    }
    if (anchored && track.has_plane()) {
      problem.AddResidualBlock(
          PointToPlaneError::Create(track.f_host, track.plane, options.plane_sigma_m),
          MakeLoss(options.loss), h.q.data(), h.t.data(), &rho[k]);
    } else {
      problem.AddResidualBlock(DepthPriorError::Create(track.lidar_depth, options.depth_sigma_m),
                               nullptr, &rho[k]);
    }
  }
  if (observations == 0) {
    result.reason = "no UGV track is seen by two keyframes of the window";
    return result;
  }
  for (int i = 0; i + 1 < n_frames; ++i) {
    const Pose T_ab = frames[i].T_wg_c.inverse() * frames[i + 1].T_wg_c;
    problem.AddResidualBlock(
        RelativePoseError::Create(Eigen::Quaterniond(T_ab.linear()), T_ab.translation(),
                                  options.lio_sigma_t_m, options.lio_sigma_rot_deg * kDegToRad),
        nullptr, poses[i].q.data(), poses[i].t.data(), poses[i + 1].q.data(),
        poses[i + 1].t.data());
  }
  if (anchored) {
    // Gauge: the map planes, and each pose's loose prior towards LIO.
    for (int i = 0; i < n_frames; ++i) {
      const Pose& T = frames[i].T_wg_c;
      problem.AddResidualBlock(PosePriorError::Create(Eigen::Quaterniond(T.linear()),
                                                      T.translation(), options.pose_prior_sigma_t_m,
                                                      options.pose_prior_sigma_rot_deg * kDegToRad),
                               nullptr, poses[i].q.data(), poses[i].t.data());
    }
  } else {
    // Gauge: the oldest keyframe's pose is held; LIO relative motion and the
    // depth priors fix the rest (scale included).
    poses[0].SetConstant(&problem);
  }
  result.anchored_to_map = anchored;
  result.plane_tracks = plane_tracks;

  ceres::Solver::Summary summary;
  ceres::Solve(SolverOptions(options.max_iterations), &problem, &summary);
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.iterations = static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable()) {
    result.reason = "stage 1 solver: " + summary.message;
    return result;
  }
  for (const PoseBlock& p : poses) result.T_wg_c.push_back(p.ToPose());
  for (size_t k = 0; k < tracks.size(); ++k) {
    const double depth = 1.0 / rho[k];
    const Eigen::Vector3d p_c(tracks[k].f_host.x() * depth, tracks[k].f_host.y() * depth, depth);
    result.points_wg.push_back(result.T_wg_c[tracks[k].host_frame] * p_c);
    result.depths.push_back(depth);
  }
  result.success = true;
  return result;
}

Stage2Result RunStage2(const Pose& T_wa_wg_initial, const std::vector<AirFrame>& air_frames,
                       const std::vector<AirGroundObservation>& observations,
                       const std::vector<PairEstimate>& pairs, const Stage2Options& options) {
  Stage2Result result;
  if (air_frames.empty()) {
    result.reason = "stage 2 needs at least one UAV keyframe";
    return result;
  }
  ceres::Problem problem;
  std::array<double, 4> x = {T_wa_wg_initial.translation().x(), T_wa_wg_initial.translation().y(),
                             T_wa_wg_initial.translation().z(),
                             ProjectedYaw(T_wa_wg_initial.linear())};
  problem.AddParameterBlock(x.data(), 4);
  std::vector<PoseBlock> poses;
  poses.reserve(air_frames.size());
  for (const AirFrame& f : air_frames) poses.emplace_back(f.T_wa_c);
  for (PoseBlock& p : poses) p.AddTo(&problem);

  int measurements = 0;
  int reprojection_residuals = 0;
  if (options.use_reprojection) {
    for (const AirGroundObservation& o : observations) {
      PoseBlock& a = poses[o.air_frame];
      problem.AddResidualBlock(AirGroundReprojectionError::Create(air_frames[o.air_frame].camera,
                                                                  o.p_wg, o.uv, options.sigma_px),
                               MakeLoss(options.loss), x.data(), a.q.data(), a.t.data());
      ++measurements;
      ++reprojection_residuals;
    }
  }
  if (options.use_consistency) {
    for (const PairEstimate& p : pairs) {
      PoseBlock& a = poses[p.air_frame];
      const double s = 1.0 / std::sqrt(std::max(p.weight, 1e-6));
      problem.AddResidualBlock(
          RelativePoseConsistencyError::Create(
              Eigen::Quaterniond(p.T_ca_wg.linear()), p.T_ca_wg.translation(),
              options.consistency_sigma_t_m * s, options.consistency_sigma_yaw_deg * kDegToRad * s),
          MakeLoss(options.loss), x.data(), a.q.data(), a.t.data());
      ++measurements;
    }
  }
  if (measurements == 0) {
    result.reason = "stage 2 has no air-ground measurement";
    return result;
  }
  // VIO relative-motion priors between consecutive UAV keyframes in time.
  std::vector<int> order(air_frames.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return air_frames[a].t_ns < air_frames[b].t_ns; });
  for (size_t i = 0; i + 1 < order.size(); ++i) {
    const int a = order[i];
    const int b = order[i + 1];
    const double dt = 1e-9 * static_cast<double>(air_frames[b].t_ns - air_frames[a].t_ns);
    const Pose T_ab = air_frames[a].T_wa_c.inverse() * air_frames[b].T_wa_c;
    const double sigma_t = std::max(options.vio_sigma_floor_t_m, options.vio_sigma_t_per_s * dt);
    const double sigma_r =
        std::max(options.vio_sigma_floor_rot_deg, options.vio_sigma_rot_deg_per_s * dt) * kDegToRad;
    problem.AddResidualBlock(RelativePoseError::Create(Eigen::Quaterniond(T_ab.linear()),
                                                       T_ab.translation(), sigma_t, sigma_r),
                             nullptr, poses[a].q.data(), poses[a].t.data(), poses[b].q.data(),
                             poses[b].t.data());
  }
  // Gauge: the air world is the VIO's; its newest keyframe pose is taken as
  // exact, so T_wa_wg is expressed in the VIO frame the UAV uses now.
  poses[order.back()].SetConstant(&problem);

  ceres::Solver::Summary summary;
  ceres::Solve(SolverOptions(options.max_iterations), &problem, &summary);
  result.iterations = static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable() || !std::isfinite(summary.final_cost)) {
    result.reason = "stage 2 solver: " + summary.message;
    return result;
  }
  result.T_wa_wg = MakePose4Dof(x[0], x[1], x[2], WrapAngle(x[3]));
  for (const PoseBlock& p : poses) result.T_wa_c.push_back(p.ToPose());

  double sum_sq = 0;
  int counted = 0;
  for (const AirGroundObservation& o : observations) {
    const Eigen::Vector3d p_ca = result.T_wa_c[o.air_frame].inverse() * (result.T_wa_wg * o.p_wg);
    Eigen::Vector2d uv;
    if (!air_frames[o.air_frame].camera->Project(p_ca, &uv)) continue;
    sum_sq += (uv - o.uv).squaredNorm();
    ++counted;
  }
  result.rms_reprojection_px = counted ? std::sqrt(sum_sq / counted) : 0.0;

  if (options.compute_covariance) {
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.null_space_rank = -1;  // pseudo-inverse: tolerate weakly observed UAV poses
    co.num_threads = 1;
    ceres::Covariance covariance(co);
    std::vector<std::pair<const double*, const double*>> blocks = {{x.data(), x.data()}};
    if (covariance.Compute(blocks, &problem)) {
      Eigen::Matrix<double, 4, 4, Eigen::RowMajor> C;
      covariance.GetCovarianceBlock(x.data(), x.data(), C.data());
      // Reduced chi-square: inflate (never shrink) to what the residuals show.
      const int dof = summary.num_residuals_reduced - summary.num_effective_parameters_reduced;
      const double chi2 = dof > 0 ? 2.0 * summary.final_cost / dof : 1.0;
      result.covariance = C * std::max(1.0, chi2);
      result.has_covariance = result.covariance.allFinite();
    }
  }
  result.success = true;
  return result;
}

}  // namespace ag
