#include "ground_server/odometry/odometry_buffer.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace ag {

const char* ToString(OdometryAddStatus status) {
  switch (status) {
    case OdometryAddStatus::kAdded:
      return "added";
    case OdometryAddStatus::kOutOfOrder:
      return "out of order (older than the newest pose)";
    case OdometryAddStatus::kDuplicate:
      return "duplicate timestamp";
    case OdometryAddStatus::kNonFinite:
      return "non-finite pose";
    case OdometryAddStatus::kNotRotation:
      return "rotation not orthonormal";
  }
  return "unknown";
}

const char* ToString(PoseLookupStatus status) {
  switch (status) {
    case PoseLookupStatus::kOk:
      return "ok";
    case PoseLookupStatus::kWait:
      return "wait";
    case PoseLookupStatus::kRefuse:
      return "refuse";
  }
  return "unknown";
}

OdometryBuffer::OdometryBuffer() : OdometryBuffer(Options()) {}

OdometryBuffer::OdometryBuffer(const Options& options) : options_(options) { options_.Check(); }

int64_t OdometryBuffer::BodyTimeNs(int64_t t_sensor_ns, double time_offset_s) {
  return t_sensor_ns + std::llround(time_offset_s * 1e9);
}

OdometryAddStatus OdometryBuffer::Add(const StampedPose& T_wg_body) {
  OdometryAddStatus status = OdometryAddStatus::kAdded;
  if (!T_wg_body.T.matrix().allFinite()) {
    status = OdometryAddStatus::kNonFinite;
  } else if (!IsRotation(T_wg_body.T.linear())) {
    status = OdometryAddStatus::kNotRotation;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (status == OdometryAddStatus::kAdded && !poses_.empty()) {
      if (T_wg_body.t_ns == poses_.back().t_ns) {
        status = OdometryAddStatus::kDuplicate;
      } else if (T_wg_body.t_ns < poses_.back().t_ns) {
        status = OdometryAddStatus::kOutOfOrder;
      }
    }
    if (status != OdometryAddStatus::kAdded) {
      ++num_rejected_;
      return status;
    }
    poses_.push_back(T_wg_body);
    while (poses_.size() > static_cast<size_t>(options_.max_poses)) {
      poses_.pop_front();
      ++num_dropped_;
    }
  }
  added_.notify_all();
  return status;
}

PoseLookup OdometryBuffer::LookupLocked(int64_t t_body_ns) const {
  PoseLookup out;
  out.t_body_ns = t_body_ns;
  if (poses_.empty()) {
    out.status = PoseLookupStatus::kWait;
    out.reason = "no odometry yet";
    return out;
  }
  if (t_body_ns < poses_.front().t_ns) {
    out.status = PoseLookupStatus::kRefuse;
    out.reason = "time " + std::to_string(t_body_ns) + " ns is older than the oldest kept pose (" +
                 std::to_string(poses_.front().t_ns) + " ns)";
    return out;
  }
  if (t_body_ns > poses_.back().t_ns) {
    out.status = PoseLookupStatus::kWait;
    out.reason = "time " + std::to_string(t_body_ns) + " ns is newer than the newest pose (" +
                 std::to_string(poses_.back().t_ns) + " ns)";
    return out;
  }
  // The deque is not a vector, so hand the shared interpolation routine just
  // the bracketing pair: same semantics as interpolating in the whole buffer.
  const auto hi = std::lower_bound(poses_.begin(), poses_.end(), t_body_ns,
                                   [](const StampedPose& p, int64_t t) { return p.t_ns < t; });
  std::vector<StampedPose> bracket;
  if (hi->t_ns != t_body_ns) bracket.push_back(*std::prev(hi));
  bracket.push_back(*hi);
  const InterpolationResult interpolated = InterpolateInBuffer(bracket, t_body_ns);
  // The bracket always contains t_body_ns, so this holds by construction.
  out.status = interpolated.ok() ? PoseLookupStatus::kOk : PoseLookupStatus::kWait;
  out.T = interpolated.T;
  return out;
}

PoseLookup OdometryBuffer::BodyPoseAt(int64_t t_body_ns) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return LookupLocked(t_body_ns);
}

PoseLookup OdometryBuffer::SensorPoseAt(int64_t t_sensor_ns, const SensorMount& mount) const {
  PoseLookup out = BodyPoseAt(BodyTimeNs(t_sensor_ns, mount.time_offset_s));
  if (out.ok()) out.T = out.T * mount.T_body_sensor;
  return out;
}

SensorTwist OdometryBuffer::SensorTwistAt(int64_t t_sensor_ns, const SensorMount& mount,
                                          double half_window_s) const {
  SensorTwist twist;
  const int64_t half = static_cast<int64_t>(std::llround(half_window_s * 1e9));
  if (half <= 0) return twist;
  PoseLookup a = SensorPoseAt(t_sensor_ns - half, mount);
  PoseLookup b = SensorPoseAt(t_sensor_ns + half, mount);
  const PoseLookup at = SensorPoseAt(t_sensor_ns, mount);
  if (!b.ok()) {
    b = at;
    a = SensorPoseAt(t_sensor_ns - 2 * half, mount);
  }
  if (!a.ok() || !b.ok() || !at.ok()) return twist;
  const double dt = 2e-9 * static_cast<double>(half);
  // The rotation from a to b in a's frame, brought to the sensor's at t.
  const Eigen::AngleAxisd w(a.T.linear().transpose() * b.T.linear());
  twist.omega = at.T.linear().transpose() * a.T.linear() * (w.axis() * (w.angle() / dt));
  twist.v_wg = (b.T.translation() - a.T.translation()) / dt;
  twist.ok = twist.omega.allFinite() && twist.v_wg.allFinite();
  return twist;
}

PoseLookup OdometryBuffer::WaitForSensorPose(int64_t t_sensor_ns, const SensorMount& mount,
                                             std::chrono::nanoseconds timeout) const {
  const int64_t t_body_ns = BodyTimeNs(t_sensor_ns, mount.time_offset_s);
  std::unique_lock<std::mutex> lock(mutex_);
  added_.wait_for(lock, timeout,
                  [&] { return closed_ || (!poses_.empty() && poses_.back().t_ns >= t_body_ns); });
  PoseLookup out = LookupLocked(t_body_ns);
  if (out.ok()) out.T = out.T * mount.T_body_sensor;
  return out;
}

void OdometryBuffer::Close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
  }
  added_.notify_all();
}

size_t OdometryBuffer::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return poses_.size();
}

std::optional<int64_t> OdometryBuffer::oldest_t_ns() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (poses_.empty()) return std::nullopt;
  return poses_.front().t_ns;
}

std::optional<int64_t> OdometryBuffer::newest_t_ns() const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (poses_.empty()) return std::nullopt;
  return poses_.back().t_ns;
}

uint64_t OdometryBuffer::num_dropped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return num_dropped_;
}

uint64_t OdometryBuffer::num_rejected() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return num_rejected_;
}

}  // namespace ag
