// ground_server in process on memq:// (no network): hostile and unexpected
// messages on every input channel are counted in the right counter and
// never crash it, and the good data sent after them is still processed:
// odometry buffered, scans and images posed, UGV keyframes made, UAV
// keyframes stored, relative poses published. Then a replay of the UGV
// streams from the start (clock jump back) resets the UGV state and is
// processed instead of rejected; and a second server on the same
// persistence directory restores the UAV keyframes and cameras.
//
// Data: the playback fixture's geometry (tests/support/playback_fixture.h)
// generated in memory; UAV keyframes are synthetic (random SIFT-like
// descriptors), enough for storage and retrieval, not for a fix.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <random>
#include <thread>

#include "common/dataset/dataset.h"
#include "common/wire/channels.h"
#include "common/wire/keyframe_codec.h"
#include "common/wire/message_codec.h"
#include "ground_server/server/ground_server_app.h"
#include "lcmtypes/checked_decode.h"
#include "tests/support/playback_fixture.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

constexpr int64_t kT0 = 1700000000000000000;
constexpr int kWidth = 160;
constexpr int kHeight = 120;

int64_t Ns(double s) { return static_cast<int64_t>(std::llround(s * 1e9)); }

template <class Msg>
std::vector<uint8_t> Encode(const Msg& msg) {
  std::vector<uint8_t> bytes(msg.getEncodedSize());
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

aglcm::camera_info_t CameraInfoMessage(const std::string& agent, const std::string& camera_id) {
  aglcm::camera_info_t m;
  m.agent = agent;
  m.camera_id = camera_id;
  m.t_ns = kT0;
  m.model = "pinhole";
  m.width = kWidth;
  m.height = kHeight;
  m.intrinsics[0] = m.intrinsics[1] = 0.8 * kWidth;
  m.intrinsics[2] = 0.5 * (kWidth - 1);
  m.intrinsics[3] = 0.5 * (kHeight - 1);
  m.num_distortion = 0;
  m.has_T_body_camera = false;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m.T_body_camera[r][c] = r == c ? 1.0 : 0.0;
  }
  m.time_offset_s = 0;
  return m;
}

/// The fixture's UGV odometry message at t_ns, with the pose of fixture time pose_t (s).
aglcm::odometry_t OdometryAt(int64_t t_ns, double pose_t) {
  StampedPose p;
  p.t_ns = t_ns;
  p.T = test::FixturePose(pose_t, 0);
  return EncodeOdometry(p, "wg", "body");
}

/// A valid UAV keyframe packet with random unit descriptors.
aglcm::air_keyframe_t AirPacket(const std::string& agent, int64_t seq, const std::string& camera,
                                const std::string& descriptor_type = "sift") {
  std::mt19937 rng(static_cast<uint32_t>(seq + 7));
  std::normal_distribution<float> normal;
  AirKeyframe kf;
  kf.agent = agent;
  kf.seq = seq;
  kf.t_ns = kT0 + Ns(static_cast<double>(seq));
  kf.camera_id = camera;
  kf.T_wa_c = test::FixturePose(static_cast<double>(seq), 0.3);
  const int n = 200;
  kf.features.descriptor_type = descriptor_type;
  kf.features.descriptors = cv::Mat(n, 128, CV_32F);
  for (int i = 0; i < n; ++i) {
    kf.features.keypoints.emplace_back(static_cast<float>(rng() % kWidth),
                                       static_cast<float>(rng() % kHeight));
    kf.features.scores.push_back(1.0f - 0.001f * static_cast<float>(i));
    cv::Mat row = kf.features.descriptors.row(i);
    for (int j = 0; j < 128; ++j) row.at<float>(j) = std::abs(normal(rng));
    cv::normalize(row, row);
  }
  kf.global_descriptor.resize(512);
  double norm = 0;
  for (float& g : kf.global_descriptor) {
    g = normal(rng);
    norm += g * g;
  }
  for (float& g : kf.global_descriptor) g = static_cast<float>(g / std::sqrt(norm));
  return EncodeKeyframe(kf, PacketFormat{});
}

/// The UGV streams of `seconds` from kT0: odometry at 50 Hz, images and
/// scans at 10 Hz, in time order (odometry first at equal times), as
/// (channel, bytes).
std::vector<std::pair<std::string, std::vector<uint8_t>>> UgvStreams(double seconds) {
  std::vector<std::pair<int64_t, std::pair<std::string, std::vector<uint8_t>>>> timed;
  for (int i = 0; i <= static_cast<int>(seconds * 50); ++i) {
    const double t = i / 50.0;
    timed.push_back({Ns(t) * 4, {kUgvOdometryChannel, Encode(OdometryAt(kT0 + Ns(t), t))}});
  }
  for (int i = 1; i < static_cast<int>(seconds * 10); ++i) {
    const double t = i / 10.0;
    const cv::Mat image = test::FixtureImage(kWidth, kHeight, CV_8UC1, 100 + i);
    timed.push_back(
        {Ns(t) * 4 + 1, {kUgvImageChannel, Encode(EncodeImagePng(kT0 + Ns(t), "cam0", image))}});
    std::vector<Eigen::Vector3f> points;
    for (int k = 0; k < 2000; ++k) {
      const double a = 0.01 * k;
      points.emplace_back(static_cast<float>(5 * std::cos(a)), static_cast<float>(5 * std::sin(a)),
                          static_cast<float>(-0.5 + 0.001 * k));
    }
    timed.push_back(
        {Ns(t) * 4 + 2,
         {kUgvPointsChannel, Encode(EncodePointCloud(kT0 + Ns(t), "lidar", points, {}))}});
  }
  std::stable_sort(timed.begin(), timed.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::pair<std::string, std::vector<uint8_t>>> out;
  out.reserve(timed.size());
  for (auto& [t, m] : timed) out.push_back(std::move(m));
  return out;
}

/// Runs a GroundServerApp on a memq:// LCM in a thread.
class ServerRunner {
 public:
  ServerRunner(const GroundServerOptions& options, lcm::LCM* lcm)
      : app_(options, lcm), thread_([this] { app_.Run(stop_); }) {}
  ~ServerRunner() { Stop(); }
  void Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  GroundServerApp& app() { return app_; }

  /// Polls (every 20 ms, at most timeout_s) until `done(stats)`.
  bool WaitFor(const std::function<bool(const GroundServerStats&)>& done, double timeout_s) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    while (std::chrono::steady_clock::now() < end) {
      if (done(app_.stats())) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return done(app_.stats());
  }

 private:
  std::atomic<bool> stop_{false};
  GroundServerApp app_;
  std::thread thread_;
};

std::string Describe(const GroundServerStats& s) {
  return "bad " + std::to_string(s.bad_messages) + ", frame id mismatches " +
         std::to_string(s.frame_id_mismatches) + ", odometry " + std::to_string(s.odometry) +
         " (rejected " + std::to_string(s.odometry_rejected) + ", clock jumps " +
         std::to_string(s.clock_jumps) + "), scans " + std::to_string(s.scans) + " (dropped " +
         std::to_string(s.scans_dropped) + "), images " + std::to_string(s.images) +
         ", keyframes " + std::to_string(s.keyframes) + " (dropped " +
         std::to_string(s.keyframes_dropped) + "), air packets " + std::to_string(s.air_packets) +
         ", stored " + std::to_string(s.air_keyframes) + " (rejected " +
         std::to_string(s.air_keyframes_rejected) + ", unknown camera " +
         std::to_string(s.air_keyframes_unknown_camera) + "), camera infos " +
         std::to_string(s.camera_infos) + ", relative poses " + std::to_string(s.relative_poses);
}

class GroundServerRobustness : public ::testing::Test {
 protected:
  void SetUp() override {
    WriteCalibration(tmp_ / "calibration.yaml", test::FixtureCalibration(kWidth, kHeight, true));
    options_.calibration_file = tmp_ / "calibration.yaml";
    options_.persistence_dir = tmp_ / "persist";
    options_.features.backend = "sift";  // no model needed; the UAV packets say "sift"
    options_.features.top_k = 300;
    options_.estimate_period_s = 0.2;
    options_.stats_period_s = 60;
    options_.logging.color = false;
  }
  void Publish(const std::string& channel, const std::vector<uint8_t>& bytes) {
    lcm_.publish(channel, bytes.data(), static_cast<unsigned>(bytes.size()));
  }
  template <class Msg>
  void Publish(const std::string& channel, const Msg& msg) {
    Publish(channel, Encode(msg));
  }

  test::TempDir tmp_;
  GroundServerOptions options_;
  lcm::LCM lcm_{"memq://"};
};

TEST_F(GroundServerRobustness, CountsHostileMessagesAndKeepsProcessingGoodData) {
  ASSERT_TRUE(lcm_.good());
  std::mutex received_mutex;
  std::vector<aglcm::relative_pose_t> received;
  struct Sink {
    std::mutex* mutex;
    std::vector<aglcm::relative_pose_t>* out;
    void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
      aglcm::relative_pose_t m;
      if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &m) < 0) return;
      std::lock_guard<std::mutex> lock(*mutex);
      out->push_back(m);
    }
  } sink{&received_mutex, &received};
  lcm::Subscription* sub = lcm_.subscribe(RelativePoseChannel("uav1"), &Sink::On, &sink);

  int64_t expect_bad = 0, expect_mismatch = 0;
  {
    ServerRunner server(options_, &lcm_);

    // --- Hostile input, before any good data.
    const std::vector<uint8_t> garbage = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
    for (const char* channel : {kUgvOdometryChannel, kUgvImageChannel, kUgvPointsChannel}) {
      Publish(channel, garbage);  // not even an LCM message of the type
      ++expect_bad;
    }
    Publish("AG_AIR_CAMERA_INFO_uav1", garbage);
    ++expect_bad;
    aglcm::odometry_t odo = OdometryAt(kT0, 0);
    std::vector<uint8_t> truncated = Encode(odo);
    truncated.resize(truncated.size() / 2);
    Publish(kUgvOdometryChannel, truncated);
    ++expect_bad;
    aglcm::odometry_t nan_odo = odo;
    nan_odo.position[1] = std::nan("");
    Publish(kUgvOdometryChannel, nan_odo);
    ++expect_bad;
    aglcm::odometry_t bad_quaternion = odo;
    bad_quaternion.orientation[0] = 3;
    Publish(kUgvOdometryChannel, bad_quaternion);
    ++expect_bad;
    aglcm::odometry_t other_world = odo;
    other_world.world_frame_id = "map";
    Publish(kUgvOdometryChannel, other_world);
    ++expect_mismatch;
    aglcm::odometry_t other_body = odo;
    other_body.body_frame_id = "imu_link";
    Publish(kUgvOdometryChannel, other_body);
    ++expect_mismatch;

    const cv::Mat small = test::FixtureImage(kWidth, kHeight, CV_8UC1, 1);
    aglcm::image_t img = EncodeImagePng(kT0, "cam0", small);
    aglcm::image_t unknown_encoding = img;
    unknown_encoding.encoding = "yuv422";
    Publish(kUgvImageChannel, unknown_encoding);
    ++expect_bad;
    aglcm::image_t big_png = EncodeImagePng(kT0, "cam0", cv::Mat(2000, 3000, CV_8UC1, 7));
    big_png.width = kWidth;  // declares a small image, holds a large one
    big_png.height = kHeight;
    Publish(kUgvImageChannel, big_png);
    ++expect_bad;
    aglcm::image_t corrupt_png = img;
    corrupt_png.data.resize(40);  // the header survives, the pixels do not
    corrupt_png.num_bytes = 40;
    Publish(kUgvImageChannel, corrupt_png);  // refused when decoded (frontend thread)
    aglcm::image_t zero_size = img;
    zero_size.width = 0;
    Publish(kUgvImageChannel, zero_size);
    ++expect_bad;
    aglcm::image_t short_raw;
    short_raw.t_ns = kT0;
    short_raw.frame_id = "cam0";
    short_raw.width = 100;
    short_raw.height = 100;
    short_raw.encoding = "mono8";
    short_raw.step = 100;
    short_raw.data.assign(50, 0);  // 100x100 declared, 50 bytes given
    short_raw.num_bytes = 50;
    Publish(kUgvImageChannel, short_raw);
    ++expect_bad;
    aglcm::image_t other_camera = img;
    other_camera.frame_id = "cam1";
    Publish(kUgvImageChannel, other_camera);
    ++expect_mismatch;
    // A length field far larger than the datagram.
    std::vector<uint8_t> huge = Encode(img);
    const size_t length_at = huge.size() - img.data.size() - 4;  // num_bytes, big-endian
    huge[length_at] = 0x7f;
    Publish(kUgvImageChannel, huge);
    ++expect_bad;

    aglcm::point_cloud_t cloud =
        EncodePointCloud(kT0, "lidar", {Eigen::Vector3f(1, 2, 3), Eigen::Vector3f(4, 5, 6)}, {});
    aglcm::point_cloud_t bad_intensity = cloud;
    bad_intensity.intensity = {1.0f};
    bad_intensity.num_intensities = 1;
    Publish(kUgvPointsChannel, bad_intensity);
    ++expect_bad;
    aglcm::point_cloud_t other_lidar = cloud;
    other_lidar.frame_id = "velodyne";
    Publish(kUgvPointsChannel, other_lidar);
    ++expect_mismatch;

    // UAV side: decoded on the keyframe thread.
    Publish("AG_AIR_KEYFRAME_uav1", garbage);
    ++expect_bad;
    Publish("AG_AIR_KEYFRAME_uav2", AirPacket("uav1", 0, "cam0"));  // another agent's channel
    ++expect_bad;
    aglcm::air_keyframe_t nan_pose = AirPacket("uav1", 0, "cam0");
    nan_pose.position[0] = std::nan("");
    Publish("AG_AIR_KEYFRAME_uav1", nan_pose);
    ++expect_bad;
    aglcm::air_keyframe_t bad_encoding = AirPacket("uav1", 0, "cam0");
    bad_encoding.descriptors.encoding = 9;
    Publish("AG_AIR_KEYFRAME_uav1", bad_encoding);
    ++expect_bad;
    aglcm::air_keyframe_t bad_count = AirPacket("uav1", 0, "cam0");
    bad_count.descriptors.count = 3;  // rows != keypoints
    Publish("AG_AIR_KEYFRAME_uav1", bad_count);
    ++expect_bad;
    Publish("AG_AIR_KEYFRAME_uav1", AirPacket("uav1", 0, "cam0", "xfeat"));  // foreign features
    ++expect_bad;
    aglcm::camera_info_t bad_model = CameraInfoMessage("uav1", "cam0");
    bad_model.model = "fisheye9";
    Publish("AG_AIR_CAMERA_INFO_uav1", bad_model);
    ++expect_bad;
    Publish("AG_AIR_CAMERA_INFO_uav2", CameraInfoMessage("uav1", "cam0"));  // wrong channel
    ++expect_bad;
    // A valid keyframe before its camera_info: stored, counted.
    Publish("AG_AIR_KEYFRAME_uav1", AirPacket("uav1", 0, "cam0"));

    ASSERT_TRUE(server.WaitFor(
        [&](const GroundServerStats& s) {
          return s.bad_messages >= expect_bad && s.air_keyframes >= 1;
        },
        20))
        << Describe(server.app().stats());

    // --- Good data.
    Publish("AG_AIR_CAMERA_INFO_uav1", CameraInfoMessage("uav1", "cam0"));
    for (int seq = 1; seq <= 3; ++seq)
      Publish("AG_AIR_KEYFRAME_uav1", AirPacket("uav1", seq, "cam0"));
    const auto ugv = UgvStreams(3.0);
    int64_t good_odometry = 0, good_scans = 0, good_images = 0;
    for (const auto& [channel, bytes] : ugv) {
      Publish(channel, bytes);
      good_odometry += channel == kUgvOdometryChannel;
      good_scans += channel == kUgvPointsChannel;
      good_images += channel == kUgvImageChannel;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    // A stray odometry stamp 100 s back, then the timeline goes on: an
    // outlier, not a clock jump.
    Publish(kUgvOdometryChannel, OdometryAt(kT0 - Ns(100), 0));
    Publish(kUgvOdometryChannel, OdometryAt(kT0 + Ns(3.01), 3.01));
    ++good_odometry;
    // A duplicate stamp.
    Publish(kUgvOdometryChannel, OdometryAt(kT0 + Ns(3.01), 3.01));

    const bool processed = server.WaitFor(
        [&](const GroundServerStats& s) {
          return s.odometry >= good_odometry && s.scans >= good_scans && s.images >= good_images &&
                 s.keyframes >= 4 && s.air_keyframes >= 4 && s.relative_poses >= 2 &&
                 s.odometry_rejected >= 2;
        },
        30);
    GroundServerStats s = server.app().stats();
    ASSERT_TRUE(processed) << Describe(s);
    EXPECT_EQ(s.bad_messages, expect_bad + 1) << "+1: the corrupt PNG, refused when decoded\n"
                                              << Describe(s);
    EXPECT_EQ(s.frame_id_mismatches, expect_mismatch) << Describe(s);
    EXPECT_EQ(s.odometry, good_odometry) << Describe(s);
    EXPECT_EQ(s.odometry_rejected, 2) << "the stray stamp and the duplicate\n" << Describe(s);
    EXPECT_EQ(s.clock_jumps, 0) << Describe(s);
    EXPECT_EQ(s.scans, good_scans) << Describe(s);
    EXPECT_EQ(s.images, good_images + 1) << "+1: the corrupt PNG passes the header checks\n"
                                         << Describe(s);
    EXPECT_EQ(s.air_packets, 10) << Describe(s);
    EXPECT_EQ(s.air_keyframes, 4) << Describe(s);
    EXPECT_EQ(s.air_keyframes_unknown_camera, 1) << Describe(s);
    EXPECT_EQ(s.air_keyframes_rejected, 0) << Describe(s);
    EXPECT_EQ(s.camera_infos, 1) << Describe(s);
    EXPECT_EQ(server.app().PlaceDbSize(), 4);

    // --- The UGV streams replayed from the start: a clock jump back,
    // confirmed by consecutive messages; the UGV state is reset and the
    // replay is processed, not rejected.
    const int64_t keyframes_before = s.keyframes;
    for (const auto& [channel, bytes] : UgvStreams(2.0)) {
      Publish(channel, bytes);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    const bool replayed = server.WaitFor(
        [&](const GroundServerStats& st) {
          return st.clock_jumps == 1 && st.keyframes >= keyframes_before + 3;
        },
        30);
    s = server.app().stats();
    EXPECT_TRUE(replayed) << Describe(s);
    EXPECT_EQ(s.clock_jumps, 1) << Describe(s);
    EXPECT_EQ(s.odometry_rejected, 2) << "the replay must not be rejected\n" << Describe(s);
    server.Stop();
    EXPECT_GE(server.app().stats().saves, 1) << "Run saves the persistence directory on exit";
  }
  lcm_.unsubscribe(sub);
  {
    std::lock_guard<std::mutex> lock(received_mutex);
    ASSERT_FALSE(received.empty());
    RelativePoseEstimate e;
    std::string error;
    EXPECT_TRUE(DecodeRelativePose(received.back(), &e, &error)) << error;
    EXPECT_EQ(e.agent, "uav1");
    for (size_t i = 1; i < received.size(); ++i)
      EXPECT_EQ(received[i].seq, received[i - 1].seq + 1);
  }

  // --- A second server on the same persistence directory: the UAV
  // keyframes and the camera come back without the UAV resending them.
  {
    GroundServerApp restarted(options_, &lcm_);
    EXPECT_EQ(restarted.PlaceDbSize(), 4);
  }
  // A UAV that restarted meanwhile numbers from 0 again: stored after the
  // restored keyframes, not refused as duplicates.
  ServerRunner again(options_, &lcm_);
  Publish("AG_AIR_KEYFRAME_uav1", AirPacket("uav1", 0, "cam0"));
  Publish("AG_AIR_KEYFRAME_uav1", AirPacket("uav1", 1, "cam0"));
  EXPECT_TRUE(again.WaitFor([](const GroundServerStats& st) { return st.air_keyframes >= 2; }, 20))
      << Describe(again.app().stats());
  const GroundServerStats st = again.app().stats();
  EXPECT_EQ(st.air_keyframes_rejected, 0) << Describe(st);
  EXPECT_EQ(st.air_keyframes_unknown_camera, 0) << "the camera was restored\n" << Describe(st);
  EXPECT_EQ(st.air_restarts, 1) << Describe(st);
  EXPECT_EQ(again.app().PlaceDbSize(), 6);
}

TEST_F(GroundServerRobustness, ServesOnlyTheConfiguredAirAgents) {
  ASSERT_TRUE(lcm_.good());
  options_.persistence_dir.clear();
  options_.air_agents = "uav1|uav3";
  ServerRunner server(options_, &lcm_);
  for (const std::string agent : {"uav1", "uav2", "uav3", "uav10"}) {
    Publish(AirCameraInfoChannel(agent), CameraInfoMessage(agent, "cam0"));
    for (int64_t seq = 0; seq < 2; ++seq) {
      Publish(AirKeyframeChannel(agent), AirPacket(agent, seq, "cam0"));
    }
  }
  const bool stored =
      server.WaitFor([](const GroundServerStats& s) { return s.air_keyframes >= 4; }, 10.0);
  // uav2 and uav10 (the pattern matches whole names) are not listened to.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const GroundServerStats s = server.app().stats();
  EXPECT_TRUE(stored) << Describe(s);
  EXPECT_EQ(s.air_packets, 4) << Describe(s);
  EXPECT_EQ(s.air_keyframes, 4) << Describe(s);
  EXPECT_EQ(s.camera_infos, 2) << Describe(s);
  EXPECT_EQ(s.bad_messages, 0) << Describe(s);
}

}  // namespace
}  // namespace ag
