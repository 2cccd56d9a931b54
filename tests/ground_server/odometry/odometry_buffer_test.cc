#include "ground_server/odometry/odometry_buffer.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <thread>

#include "tests/support/option_error.h"

namespace ag {
namespace {

constexpr int64_t kSecond = 1000000000;

// A body moving at constant velocity and turning at a constant rate about a
// fixed tilted axis: linear + slerp interpolation is exact on it.
Pose TruePose(double t_s) {
  const Eigen::Vector3d axis = Eigen::Vector3d(0.2, -0.1, 1.0).normalized();
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(0.3 * t_s, axis).toRotationMatrix();
  T.translation() = Eigen::Vector3d(1.0, -2.0, 0.5) + t_s * Eigen::Vector3d(1.5, 0.5, -0.1);
  return T;
}

StampedPose At(int64_t t_ns) { return {t_ns, TruePose(static_cast<double>(t_ns) * 1e-9)}; }

double PoseDistance(const Pose& a, const Pose& b) {
  const double dt = (a.translation() - b.translation()).norm();
  const double dr = Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
  return dt + dr;
}

TEST(OdometryBufferTest, RejectsOutOfOrderDuplicateAndInvalidPosesWithoutChangingTheBuffer) {
  OdometryBuffer buffer;
  EXPECT_EQ(buffer.Add(At(10 * kSecond)), OdometryAddStatus::kAdded);
  EXPECT_EQ(buffer.Add(At(11 * kSecond)), OdometryAddStatus::kAdded);
  EXPECT_EQ(buffer.Add(At(11 * kSecond)), OdometryAddStatus::kDuplicate);
  EXPECT_EQ(buffer.Add(At(10 * kSecond + 1)), OdometryAddStatus::kOutOfOrder);

  StampedPose nan_pose = At(12 * kSecond);
  nan_pose.T.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(buffer.Add(nan_pose), OdometryAddStatus::kNonFinite);
  StampedPose nan_rotation = At(12 * kSecond);
  nan_rotation.T.linear()(1, 2) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(buffer.Add(nan_rotation), OdometryAddStatus::kNonFinite);
  StampedPose scaled = At(12 * kSecond);
  scaled.T.linear() *= 1.01;
  EXPECT_EQ(buffer.Add(scaled), OdometryAddStatus::kNotRotation);

  EXPECT_EQ(buffer.size(), 2u);
  EXPECT_EQ(buffer.num_rejected(), 5u);
  EXPECT_EQ(*buffer.newest_t_ns(), 11 * kSecond);
  EXPECT_STRNE(ToString(OdometryAddStatus::kOutOfOrder), "unknown");
  // A valid later pose is still accepted after the rejections.
  EXPECT_EQ(buffer.Add(At(12 * kSecond)), OdometryAddStatus::kAdded);
}

TEST(OdometryBufferTest, DropsOldestBeyondCapacityAndRefusesTimesBeforeIt) {
  OdometryBuffer::Options options;
  options.max_poses = 5;
  OdometryBuffer buffer(options);
  for (int i = 0; i < 8; ++i) ASSERT_EQ(buffer.Add(At(i * kSecond)), OdometryAddStatus::kAdded);
  EXPECT_EQ(buffer.size(), 5u);
  EXPECT_EQ(buffer.num_dropped(), 3u);
  EXPECT_EQ(*buffer.oldest_t_ns(), 3 * kSecond);
  EXPECT_EQ(buffer.BodyPoseAt(2 * kSecond).status, PoseLookupStatus::kRefuse);
  EXPECT_FALSE(buffer.BodyPoseAt(2 * kSecond).reason.empty());
  EXPECT_TRUE(buffer.BodyPoseAt(3 * kSecond).ok());
}

TEST(OdometryBufferTest, InterpolatesLinearlyAndBySlerpAndNeverExtrapolates) {
  OdometryBuffer buffer;
  EXPECT_EQ(buffer.BodyPoseAt(0).status, PoseLookupStatus::kWait);  // empty: more may come
  for (int i = 0; i <= 10; ++i) buffer.Add(At(i * kSecond / 10));

  for (int64_t t_ns : {int64_t{0}, kSecond / 7, kSecond / 2, kSecond / 10, kSecond - 3, kSecond}) {
    const PoseLookup lookup = buffer.BodyPoseAt(t_ns);
    ASSERT_TRUE(lookup.ok()) << t_ns;
    EXPECT_LT(PoseDistance(lookup.T, TruePose(t_ns * 1e-9)), 1e-9) << t_ns;
    EXPECT_TRUE(lookup.reason.empty());
  }
  EXPECT_EQ(buffer.BodyPoseAt(-1).status, PoseLookupStatus::kRefuse);
  const PoseLookup later = buffer.BodyPoseAt(kSecond + 1);
  EXPECT_EQ(later.status, PoseLookupStatus::kWait);
  EXPECT_NE(later.reason.find("newer"), std::string::npos);
}

TEST(OdometryBufferTest, SensorPoseAppliesTimeOffsetThenExtrinsics) {
  OdometryBuffer buffer;
  for (int i = 0; i <= 20; ++i) buffer.Add(At(i * kSecond / 10));

  SensorMount camera;
  camera.T_body_sensor.linear() =
      Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  camera.T_body_sensor.translation() = Eigen::Vector3d(0.3, 0.0, 0.8);
  camera.time_offset_s = 0.0125;  // t_body = t_camera + 12.5 ms

  const int64_t t_camera_ns = 1234567891;
  const PoseLookup lookup = buffer.SensorPoseAt(t_camera_ns, camera);
  ASSERT_TRUE(lookup.ok());
  EXPECT_EQ(lookup.t_body_ns, t_camera_ns + 12500000);
  const Pose expected = TruePose((t_camera_ns + 12500000) * 1e-9) * camera.T_body_sensor;
  EXPECT_LT(PoseDistance(lookup.T, expected), 1e-9);

  // The offset decides wait / refuse at the edges.
  EXPECT_EQ(buffer.SensorPoseAt(2 * kSecond - 12500000, camera).status, PoseLookupStatus::kOk);
  EXPECT_EQ(buffer.SensorPoseAt(2 * kSecond - 12499999, camera).status, PoseLookupStatus::kWait);
  EXPECT_EQ(buffer.SensorPoseAt(-12500001, camera).status, PoseLookupStatus::kRefuse);
  EXPECT_EQ(OdometryBuffer::BodyTimeNs(100, -1e-7), 0);
}

TEST(OdometryBufferTest, WaitForSensorPoseWakesOnNewOdometryAndTimesOut) {
  OdometryBuffer buffer;
  buffer.Add(At(0));
  buffer.Add(At(kSecond / 10));
  const SensorMount lidar;

  // Times out with kWait when nothing arrives.
  const PoseLookup timed_out =
      buffer.WaitForSensorPose(kSecond / 5, lidar, std::chrono::milliseconds(20));
  EXPECT_EQ(timed_out.status, PoseLookupStatus::kWait);

  // Answers once a newer pose arrives from another thread.
  std::thread producer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    buffer.Add(At(kSecond / 4));
  });
  const PoseLookup woken = buffer.WaitForSensorPose(kSecond / 5, lidar, std::chrono::seconds(10));
  producer.join();
  ASSERT_TRUE(woken.ok());
  EXPECT_LT(PoseDistance(woken.T, TruePose(0.2)), 1e-9);

  // Refuse is answered at once, without waiting.
  EXPECT_EQ(buffer.WaitForSensorPose(-1, lidar, std::chrono::seconds(10)).status,
            PoseLookupStatus::kRefuse);

  // Close() releases a waiter long before its timeout.
  std::thread closer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    buffer.Close();
  });
  const auto start = std::chrono::steady_clock::now();
  const PoseLookup closed = buffer.WaitForSensorPose(10 * kSecond, lidar, std::chrono::seconds(30));
  closer.join();
  EXPECT_EQ(closed.status, PoseLookupStatus::kWait);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
}

TEST(OdometryBufferTest, ConcurrentAddAndLookupStayConsistent) {
  OdometryBuffer::Options options;
  options.max_poses = 50;
  OdometryBuffer buffer(options);
  constexpr int kPoses = 2000;
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (int i = 0; i < kPoses; ++i) buffer.Add(At(i * kSecond / 100));
    done = true;
  });
  int checked = 0;
  int bad = 0;
  while (!done || checked == 0) {
    const auto newest = buffer.newest_t_ns();
    if (!newest) continue;
    const int64_t t_ns = *newest - kSecond / 200;  // between two poses, usually still kept
    const PoseLookup lookup = buffer.BodyPoseAt(t_ns);
    if (lookup.ok()) {
      ++checked;
      if (PoseDistance(lookup.T, TruePose(t_ns * 1e-9)) > 1e-9) ++bad;
    } else if (lookup.status == PoseLookupStatus::kWait) {
      ++bad;  // an older time than the newest one seen can never be "wait"
    }
  }
  producer.join();
  EXPECT_GT(checked, 0);
  EXPECT_EQ(bad, 0);
  EXPECT_EQ(buffer.size(), 50u);
  EXPECT_EQ(buffer.num_dropped(), static_cast<uint64_t>(kPoses - 50));
}

TEST(OdometryBufferTest, OptionsCheckNamesTheField) {
  OdometryBuffer::Options options;
  options.max_poses = 1;
  test::ExpectOptionErrorNaming("max_poses", [&] { OdometryBuffer buffer(options); });
}

TEST(OdometryBufferTest, SensorTwistIsTheMountedSensorsMotion) {
  OdometryBuffer buffer;
  for (int i = 0; i <= 200; ++i)
    ASSERT_EQ(buffer.Add(At(i * kSecond / 100)), OdometryAddStatus::kAdded);
  SensorMount mount;
  mount.T_body_sensor.linear() =
      Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  mount.T_body_sensor.translation() = Eigen::Vector3d(0.3, -0.1, 0.2);
  const Eigen::Vector3d omega_world = 0.3 * Eigen::Vector3d(0.2, -0.1, 1.0).normalized();
  auto expect_twist = [&](double t_s, double v_tolerance) {
    const SensorTwist twist = buffer.SensorTwistAt(static_cast<int64_t>(t_s * kSecond), mount);
    ASSERT_TRUE(twist.ok) << "t = " << t_s;
    const Pose T_wg_s = TruePose(t_s) * mount.T_body_sensor;
    // The body turns about a fixed world axis; the sensor sees that rate in
    // its own frame, and its velocity has the lever arm's part.
    EXPECT_LT((twist.omega - T_wg_s.linear().transpose() * omega_world).norm(), 1e-6) << t_s;
    const Eigen::Vector3d v =
        Eigen::Vector3d(1.5, 0.5, -0.1) +
        omega_world.cross(TruePose(t_s).linear() * mount.T_body_sensor.translation());
    EXPECT_LT((twist.v_wg - v).norm(), v_tolerance) << t_s;
  };
  expect_twist(1.0, 1e-4);  // central difference
  // The buffer ends at 2 s: a backward difference, whose velocity is the
  // mean over [1.75, 1.95] s (the lever arm's part turns by 0.06 rad).
  expect_twist(1.95, 5e-3);
  EXPECT_FALSE(buffer.SensorTwistAt(kSecond / 20, mount).ok) << "before the buffer's start";
}

}  // namespace
}  // namespace ag
