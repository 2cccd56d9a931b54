#include "common/dataset/ground_truth.h"

#include <cmath>

namespace ag {

PoseError FourDofError(const Pose& estimate, const Pose& truth) {
  PoseError e;
  e.translation_m = (estimate.translation() - truth.translation()).norm();
  e.yaw_deg = std::abs(WrapAngle(ProjectedYaw(estimate.linear()) - ProjectedYaw(truth.linear()))) *
              180.0 / M_PI;
  return e;
}

std::optional<Pose> OdometryWorldInTrueWorld(const AgentData& agent, int64_t t_ns,
                                             const Pose& body_offset) {
  const InterpolationResult odom = InterpolateInBuffer(agent.odometry, t_ns);
  const InterpolationResult truth = InterpolateInBuffer(agent.groundtruth, t_ns);
  if (!odom.ok() || !truth.ok()) return std::nullopt;
  return ProjectTo4Dof(truth.T * body_offset * odom.T.inverse());
}

Pose LidarMountOffset(const Dataset& dataset) {
  if (!dataset.groundtruth || !dataset.groundtruth->ground_true_lidar ||
      !dataset.ground.calibration.lidar) {
    return Pose::Identity();
  }
  return dataset.groundtruth->ground_true_lidar->T_body_lidar *
         dataset.ground.calibration.lidar->T_body_lidar.inverse();
}

std::optional<Pose> ObservableTruth(const Dataset& dataset, const AgentData& air, int64_t t_air,
                                    int64_t t_ground, const Pose& T_wa_wg) {
  const std::optional<Pose> T_wa_oa = OdometryWorldInTrueWorld(air, t_air);
  const std::optional<Pose> T_wg_og =
      OdometryWorldInTrueWorld(dataset.ground, t_ground, LidarMountOffset(dataset));
  if (!T_wa_oa || !T_wg_og) return std::nullopt;
  return ProjectTo4Dof(T_wa_oa->inverse() * T_wa_wg * *T_wg_og);
}

}  // namespace ag
