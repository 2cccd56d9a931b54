#pragma once

// What the ground truth of a dataset says an estimate of T_wa_wg could have
// been: groundtruth.yaml holds the relation of the two true worlds, while an
// estimator only sees the two odometry worlds, which drift. Shared by the
// offline evaluator and the live relative-pose monitor, so both report the
// same "drift-free" error.

#include <cstdint>
#include <optional>

#include "common/dataset/dataset.h"
#include "common/geometry/pose.h"

namespace ag {

/// Translation (m) and yaw (deg) error of an estimated T_wa_wg, as the
/// paper and the report spec measure them.
struct PoseError {
  double translation_m = 0;
  double yaw_deg = 0;
};
PoseError FourDofError(const Pose& estimate, const Pose& truth);

/// Where an agent's odometry world is in its true world at t_ns:
/// T_world_odom = T_world_body(t) T_odom_body(t)^-1 (identity without
/// drift), projected to 4-DoF. `body_offset` is what the odometry tracks
/// instead of the body (LIO tracks the LiDAR: T_b_l_true T_b_l_nominal^-1),
/// so that a constant mounting error is not mistaken for drift. Empty when
/// t_ns is outside the agent's odometry or ground-truth trajectory.
std::optional<Pose> OdometryWorldInTrueWorld(const AgentData& agent, int64_t t_ns,
                                             const Pose& body_offset = Pose::Identity());

/// What LIO's reported body is off by when the LiDAR's true mounting differs
/// from the nominal one: T_b_l_true T_b_l_nominal^-1; identity without the
/// true calibration.
Pose LidarMountOffset(const Dataset& dataset);

/// The relation between the two odometry worlds when an estimate was made
/// (UAV keyframe at t_air, air clock; UGV at t_ground, ground clock): the
/// true T_wa_wg with both agents' odometry drift applied. No estimator can do
/// better than this from odometry-world data; its difference to
/// groundtruth.yaml is drift. Empty when a time is outside a trajectory.
std::optional<Pose> ObservableTruth(const Dataset& dataset, const AgentData& air, int64_t t_air,
                                    int64_t t_ground, const Pose& T_wa_wg);

}  // namespace ag
