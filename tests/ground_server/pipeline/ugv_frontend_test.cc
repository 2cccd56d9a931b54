#include "ground_server/pipeline/ugv_frontend.h"

#include <gtest/gtest.h>

#include "tests/support/synthetic_views.h"

namespace ag {
namespace {

constexpr int64_t kMs = 1000000;

TEST(UgvFrontendTest, AnImageWaitsForTheOdometryPastItForItsCamerasMotion) {
  AgentCalibration calibration;
  calibration.camera.camera = test::Pinhole640x480();
  calibration.camera.time_offset_s = 0.02;  // the body time of an image is 20 ms later
  const UgvFrontend frontend(calibration, nullptr, nullptr, UgvFrontend::Options());
  OdometryBuffer odometry;
  for (int64_t t = 1000; t <= 1200; t += 10) {
    Pose T = Pose::Identity();
    T.translation().x() = 1e-3 * static_cast<double>(t);
    ASSERT_EQ(odometry.Add({t * kMs, T}), OdometryAddStatus::kAdded);
  }
  // Body times 1020 and 1100 ms: known, and so is 100 ms past them.
  EXPECT_EQ(frontend.ImageReady(1000 * kMs, odometry), PoseLookupStatus::kOk);
  EXPECT_EQ(frontend.ImageReady(1080 * kMs, odometry), PoseLookupStatus::kOk);
  // Body time 1120 ms is known, 1220 ms not yet.
  EXPECT_EQ(frontend.ImageReady(1100 * kMs, odometry), PoseLookupStatus::kWait);
  // Before the odometry's start: never.
  EXPECT_EQ(frontend.ImageReady(900 * kMs, odometry), PoseLookupStatus::kRefuse);
  // And once it is ready, the camera's motion is known there (whether it is
  // the central or the backward difference, this linear motion cannot tell:
  // OdometryBufferTest.SensorTwistIsTheMountedSensorsMotion does).
  const SensorTwist twist =
      odometry.SensorTwistAt(1080 * kMs, {Pose::Identity(), 0.02}, UgvFrontend::kTwistHalfWindowS);
  ASSERT_TRUE(twist.ok);
  EXPECT_NEAR(twist.v_wg.x(), 1.0, 1e-9);
}

}  // namespace
}  // namespace ag
