#pragma once

// The UGV's LIO trajectory as a bounded, time-sorted, thread-safe buffer, and
// the pose of a rigidly mounted sensor (camera, LiDAR) at its own timestamp.
//
// Paper, "System Overview": the UGV camera pose is "obtained through linear
// interpolation of the LIO poses". With the calibration of
// shared/spec/dataset.md (t_body = t_sensor + time_offset_s):
//   T_wg_sensor(t_sensor) = Interp(T_wg_body, t_sensor + offset) * T_body_sensor
// Interpolation is linear in translation and slerp in rotation
// (ag::InterpolateInBuffer). Outside the buffered span there is no answer:
// newer than the newest pose means "wait for odometry", older than the oldest
// kept pose means "refuse"; a pose is never extrapolated.

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>

#include "common/core/error.h"
#include "common/geometry/pose.h"

namespace ag {

/// Extrinsic and time calibration of a sensor rigidly mounted on the body.
struct SensorMount {
  Pose T_body_sensor = Pose::Identity();  ///< sensor frame -> body frame
  double time_offset_s = 0.0;             ///< t_body = t_sensor + time_offset_s (s)
};

/// Why Add() accepted or rejected a pose.
enum class OdometryAddStatus {
  kAdded,
  kOutOfOrder,   ///< t_ns earlier than the newest buffered pose
  kDuplicate,    ///< t_ns equal to the newest buffered pose
  kNonFinite,    ///< NaN or infinity in the pose
  kNotRotation,  ///< rotation block not orthonormal with det +1 (1e-6)
};

/// Human-readable name of an add status ("added", "out of order", ...).
const char* ToString(OdometryAddStatus status);

/// Why a pose lookup has (or has no) answer.
enum class PoseLookupStatus {
  kOk,
  kWait,    ///< later than the newest pose (or empty buffer): more odometry may come
  kRefuse,  ///< earlier than the oldest kept pose: will never be answerable
};

/// Human-readable name of a lookup status ("ok", "wait", "refuse").
const char* ToString(PoseLookupStatus status);

/// A pose lookup result: the pose when status is kOk, otherwise the reason.
struct PoseLookup {
  PoseLookupStatus status = PoseLookupStatus::kWait;
  Pose T = Pose::Identity();  ///< T_wg_body or T_wg_sensor, valid only when ok()
  int64_t t_body_ns = 0;      ///< the body time that was looked up (ns)
  std::string reason;         ///< empty when ok; otherwise says which bound was crossed
  bool ok() const { return status == PoseLookupStatus::kOk; }
};

/// A sensor's motion at one time, from the odometry.
struct SensorTwist {
  bool ok = false;                                  ///< false: the buffer does not cover it
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();  ///< angular velocity, sensor frame (rad/s)
  Eigen::Vector3d v_wg = Eigen::Vector3d::Zero();   ///< velocity in wg (m/s)
};

/// Bounded, time-sorted buffer of T_wg_body poses; all methods thread-safe.
///
/// Add() accepts strictly increasing timestamps only; rejected poses come back
/// as a status, never an exception, so a glitching odometry source cannot
/// crash the daemon. When full, the oldest pose is dropped.
class OdometryBuffer {
 public:
  struct Options {
    int max_poses = 4000;  ///< poses kept; oldest dropped beyond this (20 s at 200 Hz)

    template <class V>
    void VisitFields(V& v) {
      v("max_poses", max_poses);
    }
    void Check() const { CheckOption(max_poses >= 2, "max_poses", "must be >= 2"); }
  };

  OdometryBuffer();
  /// Throws ag::OptionError if `options` are invalid.
  explicit OdometryBuffer(const Options& options);

  /// Appends T_wg_body at t_ns. Rejects out-of-order, duplicate, non-finite
  /// or non-rotation poses (the buffer is unchanged). Wakes WaitFor* callers.
  OdometryAddStatus Add(const StampedPose& T_wg_body);

  /// T_wg_body at body time `t_body_ns` (interpolated; exact hits returned).
  PoseLookup BodyPoseAt(int64_t t_body_ns) const;

  /// T_wg_sensor at sensor time `t_sensor_ns`: the body pose at
  /// t_sensor + mount.time_offset_s composed with mount.T_body_sensor.
  PoseLookup SensorPoseAt(int64_t t_sensor_ns, const SensorMount& mount) const;

  /// The sensor's motion at `t_sensor_ns`: a central difference of its
  /// poses over +-half_window_s (a short one would amplify the odometry's
  /// per-sample noise), or a backward one where the buffer does not reach
  /// t + half_window_s yet.
  SensorTwist SensorTwistAt(int64_t t_sensor_ns, const SensorMount& mount,
                            double half_window_s = 0.1) const;

  /// Like SensorPoseAt, but while the answer is kWait blocks until a newer
  /// pose arrives, Close() is called or `timeout` passes; then answers with
  /// what the buffer holds (kWait again on timeout).
  PoseLookup WaitForSensorPose(int64_t t_sensor_ns, const SensorMount& mount,
                               std::chrono::nanoseconds timeout) const;

  /// Wakes every WaitFor* caller; later waits return at once. Idempotent.
  void Close();

  size_t size() const;
  /// Time of the oldest / newest buffered pose; nullopt when empty.
  std::optional<int64_t> oldest_t_ns() const;
  std::optional<int64_t> newest_t_ns() const;
  /// Poses dropped from the front because the buffer was full.
  uint64_t num_dropped() const;
  /// Poses rejected by Add().
  uint64_t num_rejected() const;

  /// Body time of a sensor time: t_sensor + round(time_offset_s * 1e9).
  static int64_t BodyTimeNs(int64_t t_sensor_ns, double time_offset_s);

 private:
  PoseLookup LookupLocked(int64_t t_body_ns) const;

  Options options_;
  mutable std::mutex mutex_;
  mutable std::condition_variable added_;
  std::deque<StampedPose> poses_;  ///< strictly increasing t_ns
  bool closed_ = false;
  uint64_t num_dropped_ = 0;
  uint64_t num_rejected_ = 0;
};

}  // namespace ag
