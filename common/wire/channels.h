#pragma once

// LCM channel names, in one place. Per-agent channels end with the agent
// name so lcm-spy shows one row per UAV and a subscriber can use a pattern.

#include <string>

namespace ag {

inline std::string AirKeyframeChannel(const std::string& agent) {
  return "AG_AIR_KEYFRAME_" + agent;
}
inline std::string AirCameraInfoChannel(const std::string& agent) {
  return "AG_AIR_CAMERA_INFO_" + agent;
}
inline std::string RelativePoseChannel(const std::string& agent) {
  return "AG_RELATIVE_POSE_" + agent;
}
/// Regular expressions (LCM subscribe patterns) for every agent.
inline const char* kAirKeyframePattern = "AG_AIR_KEYFRAME_[a-z0-9_]+";
inline const char* kAirCameraInfoPattern = "AG_AIR_CAMERA_INFO_[a-z0-9_]+";
/// The same for the agents whose names match `agents` (a POSIX extended
/// regular expression over the whole name, as LCM matches channels).
inline std::string AirKeyframePattern(const std::string& agents) {
  return "AG_AIR_KEYFRAME_(" + agents + ")";
}
inline std::string AirCameraInfoPattern(const std::string& agents) {
  return "AG_AIR_CAMERA_INFO_(" + agents + ")";
}

/// UGV sensor streams (ground_server input, tools/play_dataset output).
inline const char* kUgvImageChannel = "AG_UGV_IMAGE";
inline const char* kUgvOdometryChannel = "AG_UGV_ODOMETRY";
inline const char* kUgvPointsChannel = "AG_UGV_POINTS";
/// UAV sensor streams, per agent (air_agent live input).
inline std::string AirImageChannel(const std::string& agent) { return "AG_AIR_IMAGE_" + agent; }
inline std::string AirOdometryChannel(const std::string& agent) {
  return "AG_AIR_ODOMETRY_" + agent;
}

}  // namespace ag
