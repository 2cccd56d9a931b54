#pragma once

// A small dataset written in a fraction of a second, for the dataset player
// and the daemons that consume its streams: a ground agent (images, scans
// with intensity, odometry) and two air agents (images, odometry), with
// timestamps chosen so streams interleave and some coincide (tie order).
// Header-only; users link ag::dataset and ag::pcd.

#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "common/dataset/dataset.h"
#include "common/pcd/pcd_io.h"

namespace ag::test {

struct PlaybackFixtureOptions {
  double duration_s = 1.0;  ///< of every stream (s)
  int64_t t0_ns = 1700000000000000000;
  double uav2_clock_offset_s = 0;  ///< uav2's clock minus the ground's (s)
  int air_width = 64;              ///< air images (px); noise, so SIFT finds features
  int air_height = 48;
};

/// A smooth pose: moving along x, swaying in y and z, yawing and tilting.
inline Pose FixturePose(double t, double phase) {
  Pose T = Pose::Identity();
  T.linear() = (Eigen::AngleAxisd(0.3 * t + phase, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(0.05 * std::sin(3 * t), Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(0.04 * std::cos(2 * t), Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(1.5 * t + phase, std::sin(t + phase), 0.2 * std::cos(t));
  return T;
}

inline AgentCalibration FixtureCalibration(int width, int height, bool lidar) {
  AgentCalibration c;
  c.camera.camera = {"pinhole",          width, height, 0.8 * width, 0.8 * width, 0.5 * (width - 1),
                     0.5 * (height - 1), {}};
  c.camera.T_body_camera.linear() =
      Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  c.camera.T_body_camera.translation() = Eigen::Vector3d(0.1, 0.0, -0.05);
  if (lidar) {
    LidarCalibration l;
    l.T_body_lidar.translation() = Eigen::Vector3d(0, 0, 0.4);
    c.lidar = l;
  }
  return c;
}

/// Textured noise (blurred, so it survives as corners at several scales).
inline cv::Mat FixtureImage(int width, int height, int type, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat noise(height / 4 + 1, width / 4 + 1, type);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat image;
  cv::resize(noise, image, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);
  return image;
}

/// Writes the fixture at `dir` (must not exist) and returns `dir`:
///  - ground: odometry at 50 Hz from t0; images (64x48 BGR) at 10 Hz from t0,
///    on odometry instants (ties); scans (20 points, intensity) at 10 Hz
///    from t0 + 50 ms;
///  - uav1: odometry at 100 Hz from t0 (ties with the ground's); images
///    (grey) at 10 Hz from t0 + 30 ms;
///  - uav2: the same in its own clock (t0 + uav2_clock_offset_s), images
///    from + 70 ms.
inline std::string WritePlaybackFixture(const std::string& dir,
                                        const PlaybackFixtureOptions& o = {}) {
  DatasetWriter writer(dir, "playback fixture", "written by tests/support/playback_fixture.h");
  writer.BeginGround(FixtureCalibration(64, 48, true));
  writer.BeginAir("uav1", FixtureCalibration(o.air_width, o.air_height, false));
  writer.BeginAir("uav2", FixtureCalibration(o.air_width, o.air_height, false));
  const auto ns = [](double s) { return static_cast<int64_t>(std::llround(s * 1e9)); };
  const int frames = static_cast<int>(std::llround(o.duration_s * 10));
  std::vector<StampedPose> ground, uav1, uav2;
  for (int i = 0; i <= frames * 5; ++i)
    ground.push_back({o.t0_ns + i * ns(0.02), FixturePose(0.02 * i, 0)});
  for (int i = 0; i <= frames * 10; ++i) {
    uav1.push_back({o.t0_ns + i * ns(0.01), FixturePose(0.01 * i, 1)});
    uav2.push_back({o.t0_ns + ns(o.uav2_clock_offset_s) + i * ns(0.01), FixturePose(0.01 * i, 2)});
  }
  for (int k = 0; k < frames; ++k) {
    const int64_t t = o.t0_ns + k * ns(0.1);
    cv::imwrite(writer.AddImage("ground", t), FixtureImage(64, 48, CV_8UC3, 100 + k));
    cv::imwrite(writer.AddImage("uav1", t + ns(0.03)),
                FixtureImage(o.air_width, o.air_height, CV_8UC1, 200 + k));
    cv::imwrite(writer.AddImage("uav2", t + ns(o.uav2_clock_offset_s) + ns(0.07)),
                FixtureImage(o.air_width, o.air_height, CV_8UC1, 300 + k));
    PointCloud cloud;
    for (int p = 0; p < 20; ++p) {
      cloud.points.emplace_back(0.5f * static_cast<float>(p), static_cast<float>(k), 1.25f);
      cloud.intensity.push_back(static_cast<float>(p + k) * 0.5f);
    }
    WriteScan(writer.AddScan(t + ns(0.05)), cloud);
  }
  writer.SetOdometry("ground", ground);
  writer.SetOdometry("uav1", uav1);
  writer.SetOdometry("uav2", uav2);
  writer.Finish();
  return dir;
}

}  // namespace ag::test
