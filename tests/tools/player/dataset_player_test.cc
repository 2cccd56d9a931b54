// The dataset player's library, without a network: the merged schedule (time
// order, ties, selection, windows, clock alignment), message contents decoded
// back and compared with the dataset (pixels, poses, points), a run through
// an in-process LCM (memq://), the pacer's arithmetic, stopping and errors.

#include "tools/player/dataset_player.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <set>

#include "common/core/error.h"
#include "common/pcd/pcd_io.h"
#include "common/wire/channels.h"
#include "common/wire/message_codec.h"
#include "lcmtypes/checked_decode.h"
#include "tests/support/playback_fixture.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

DatasetPlayerOptions Fast() {
  DatasetPlayerOptions o;
  o.speed = 0;
  o.max_rate_hz = 0;
  o.max_mbps = 0;
  return o;
}

struct Captured {
  std::string channel;
  std::vector<uint8_t> bytes;
};

/// Plays `player` to the end into a vector (no LCM).
std::vector<Captured> PlayToVector(DatasetPlayer& player, DatasetPlayerStats* stats = nullptr) {
  std::vector<Captured> out;
  std::atomic<bool> stop{false};
  const DatasetPlayerStats s = player.Run(
      [&](const std::string& channel, const std::vector<uint8_t>& bytes) {
        out.push_back({channel, bytes});
        return true;
      },
      stop);
  if (stats) *stats = s;
  return out;
}

template <class Message>
Message Decode(const std::vector<uint8_t>& bytes) {
  Message m;
  EXPECT_GT(DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &m), 0);
  return m;
}

class DatasetPlayerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::WritePlaybackFixture(tmp_ / "dataset");
    dataset_ = ReadDataset(dir_);
  }
  test::TempDir tmp_;
  std::string dir_;
  Dataset dataset_;
};

TEST_F(DatasetPlayerTest, ScheduleHasEveryRowOnceInTimeOrderOdometryFirstOnTies) {
  const std::vector<ScheduledMessage> s = BuildSchedule(dataset_, Fast());
  const size_t expected = dataset_.ground.odometry.size() + dataset_.ground.images.size() +
                          dataset_.ground.scans.size() + dataset_.air.at("uav1").odometry.size() +
                          dataset_.air.at("uav1").images.size() +
                          dataset_.air.at("uav2").odometry.size() +
                          dataset_.air.at("uav2").images.size();
  ASSERT_EQ(s.size(), expected);
  std::set<std::tuple<int, std::string, size_t>> seen;
  for (size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(s[i].play_t_ns, s[i].t_ns) << "no clock shift without align_starts";
    EXPECT_TRUE(seen.emplace(static_cast<int>(s[i].kind), s[i].agent, s[i].index).second);
    if (i == 0) continue;
    ASSERT_LE(s[i - 1].play_t_ns, s[i].play_t_ns) << "message " << i;
    if (s[i - 1].play_t_ns == s[i].play_t_ns) {
      EXPECT_LT(std::tie(s[i - 1].kind, s[i - 1].agent), std::tie(s[i].kind, s[i].agent))
          << "tie at message " << i;
    }
  }
  // The fixture's ties: at t0, ground odometry, uav1 and uav2 odometry, then
  // the ground image of the same instant.
  ASSERT_GE(s.size(), 4u);
  EXPECT_EQ(s[0].kind, StreamKind::kGroundOdometry);
  EXPECT_EQ(s[1].kind, StreamKind::kAirOdometry);
  EXPECT_EQ(s[1].agent, "uav1");
  EXPECT_EQ(s[2].kind, StreamKind::kAirOdometry);
  EXPECT_EQ(s[2].agent, "uav2");
  EXPECT_EQ(s[3].kind, StreamKind::kGroundImage);
  EXPECT_EQ(s[3].t_ns, s[0].t_ns);
  EXPECT_EQ(ChannelOf(s[0]), kUgvOdometryChannel);
  EXPECT_EQ(ChannelOf(s[2]), AirOdometryChannel("uav2"));
  EXPECT_EQ(ChannelOf(s[3]), kUgvImageChannel);
}

TEST_F(DatasetPlayerTest, SelectsAgentsAndStreams) {
  DatasetPlayerOptions o = Fast();
  o.agents = {"uav2"};
  for (const ScheduledMessage& m : BuildSchedule(dataset_, o)) EXPECT_NE(m.agent, "uav1");
  o.ground = false;
  for (const ScheduledMessage& m : BuildSchedule(dataset_, o)) EXPECT_EQ(m.agent, "uav2");
  o = Fast();
  o.air = false;
  const auto ground_only = BuildSchedule(dataset_, o);
  for (const ScheduledMessage& m : ground_only) EXPECT_EQ(m.agent, "ground");
  EXPECT_EQ(ground_only.size(), dataset_.ground.odometry.size() + dataset_.ground.images.size() +
                                    dataset_.ground.scans.size());

  o = Fast();
  o.agents = {"uav9"};
  try {
    BuildSchedule(dataset_, o);
    FAIL() << "an unknown agent must be refused";
  } catch (const OptionError& e) {
    EXPECT_EQ(e.field(), "agents");
    EXPECT_NE(std::string(e.what()).find("uav9"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("uav1, uav2"), std::string::npos) << e.what();
  }
  o = Fast();
  o.ground = false;
  o.air = false;
  EXPECT_THROW(BuildSchedule(dataset_, o), OptionError);
}

TEST_F(DatasetPlayerTest, WindowKeepsOdometryMarginsAroundIt) {
  DatasetPlayerOptions o = Fast();
  o.start_s = 0.3;
  o.duration_s = 0.4;
  o.odometry_margin_s = 0.05;
  const std::vector<ScheduledMessage> s = BuildSchedule(dataset_, o);
  ASSERT_FALSE(s.empty());
  const int64_t t0 = dataset_.ground.odometry.front().t_ns;
  const int64_t begin = t0 + 300000000, end = t0 + 700000000;
  int images = 0;
  for (const ScheduledMessage& m : s) {
    if (m.kind == StreamKind::kGroundOdometry || m.kind == StreamKind::kAirOdometry) {
      EXPECT_GE(m.play_t_ns, begin - 50000000);
      EXPECT_LE(m.play_t_ns, end + 50000000);
    } else {
      EXPECT_GE(m.play_t_ns, begin);
      EXPECT_LE(m.play_t_ns, end);
      images += m.kind == StreamKind::kGroundImage;
    }
  }
  EXPECT_EQ(images, 5);  // ground images at 0.3, 0.4, ..., 0.7 s
  EXPECT_EQ(s.front().play_t_ns, begin - 50000000)
      << "the margin's first odometry: uav1's at 0.25 s";
  EXPECT_EQ(s.back().play_t_ns, end + 50000000);
  o.start_s = 5;
  EXPECT_THROW(BuildSchedule(dataset_, o), OptionError);
}

TEST(DatasetPlayerClocks, AlignStartsShiftsPlayTimeNotTimestamps) {
  test::TempDir tmp;
  test::PlaybackFixtureOptions fo;
  fo.uav2_clock_offset_s = 1000;  // uav2's clock is 1000 s ahead
  const Dataset dataset = ReadDataset(test::WritePlaybackFixture(tmp / "dataset", fo));
  DatasetPlayerOptions o = Fast();
  const auto raw = BuildSchedule(dataset, o);
  EXPECT_EQ(raw.back().agent, "uav2") << "raw clocks: uav2 plays 1000 s after the rest";
  o.align_starts = true;
  const auto aligned = BuildSchedule(dataset, o);
  ASSERT_EQ(aligned.size(), raw.size());
  const int64_t offset = 1000000000000;
  int64_t latest = 0;
  for (const ScheduledMessage& m : aligned) {
    EXPECT_EQ(m.t_ns - m.play_t_ns, m.agent == "uav2" ? offset : 0) << m.agent;
    latest = std::max(latest, m.play_t_ns);
  }
  EXPECT_LT(latest - aligned.front().play_t_ns, 2000000000) << "one timeline of about 1 s";
}

TEST_F(DatasetPlayerTest, PublishedMessagesDecodeToTheDataset) {
  DatasetPlayer player(dataset_, Fast());
  DatasetPlayerStats stats;
  const std::vector<Captured> out = PlayToVector(player, &stats);
  const std::vector<ScheduledMessage>& s = player.schedule();
  ASSERT_EQ(out.size(), s.size());
  EXPECT_EQ(stats.messages, static_cast<int64_t>(s.size()));
  EXPECT_EQ(stats.scheduled, static_cast<int64_t>(s.size()));
  EXPECT_FALSE(stats.stopped);
  int64_t bytes = 0;
  std::map<std::string, int64_t> per_channel;
  for (size_t i = 0; i < out.size(); ++i) {
    const ScheduledMessage& m = s[i];
    const AgentData& agent = m.agent == "ground" ? dataset_.ground : dataset_.air.at(m.agent);
    ASSERT_EQ(out[i].channel, ChannelOf(m)) << "published in schedule order";
    bytes += static_cast<int64_t>(out[i].bytes.size());
    ++per_channel[out[i].channel];
    switch (m.kind) {
      case StreamKind::kGroundOdometry:
      case StreamKind::kAirOdometry: {
        const auto msg = Decode<aglcm::odometry_t>(out[i].bytes);
        EXPECT_EQ(msg.world_frame_id, m.agent == "ground" ? "wg" : "wa");
        EXPECT_EQ(msg.body_frame_id, "body");
        StampedPose pose;
        std::string error;
        ASSERT_TRUE(DecodeOdometry(msg, &pose, &error)) << error;
        const StampedPose& want = agent.odometry[m.index];
        EXPECT_EQ(pose.t_ns, want.t_ns);
        EXPECT_TRUE(pose.T.matrix().isApprox(want.T.matrix(), 1e-12)) << "odometry " << i;
        EXPECT_EQ(pose.T.translation(), want.T.translation());
        break;
      }
      case StreamKind::kGroundImage:
      case StreamKind::kAirImage: {
        const auto msg = Decode<aglcm::image_t>(out[i].bytes);
        EXPECT_EQ(msg.frame_id, "cam0");
        EXPECT_EQ(msg.encoding, "png");
        EXPECT_EQ(msg.t_ns, agent.images[m.index].t_ns);
        cv::Mat image;
        std::string error;
        ASSERT_TRUE(DecodeImage(msg, &image, &error)) << error;
        const cv::Mat want = LoadImage(agent.images[m.index]);
        ASSERT_EQ(image.type(), want.type());
        ASSERT_EQ(image.size(), want.size());
        EXPECT_EQ(cv::norm(image, want, cv::NORM_INF), 0.0) << "PNG is lossless";
        break;
      }
      case StreamKind::kGroundScan: {
        const auto msg = Decode<aglcm::point_cloud_t>(out[i].bytes);
        EXPECT_EQ(msg.frame_id, "lidar");
        EXPECT_EQ(msg.t_ns, agent.scans[m.index].t_ns);
        std::vector<Eigen::Vector3f> points;
        std::vector<float> intensity;
        std::string error;
        ASSERT_TRUE(DecodePointCloud(msg, &points, &intensity, &error)) << error;
        const PointCloud want = ReadScan(agent.scans[m.index].path);
        EXPECT_EQ(points, want.points);
        EXPECT_EQ(intensity, want.intensity);
        EXPECT_FALSE(intensity.empty());
        break;
      }
    }
  }
  EXPECT_EQ(stats.bytes, bytes);
  ASSERT_EQ(stats.channels.size(), per_channel.size());
  for (const auto& [channel, n] : per_channel) EXPECT_EQ(stats.channels.at(channel).messages, n);
  EXPECT_EQ(per_channel.at(kUgvPointsChannel), static_cast<int64_t>(dataset_.ground.scans.size()));
  const std::string summary = FormatSummary(stats);
  EXPECT_NE(summary.find("AG_AIR_IMAGE_uav2"), std::string::npos) << summary;
  EXPECT_NE(summary.find(std::to_string(stats.bytes)), std::string::npos) << summary;
}

TEST_F(DatasetPlayerTest, InProcessLcmReceivesTheScheduleInOrder) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  struct Receiver {
    std::vector<std::string> channels;
    std::vector<int64_t> t_ns;
    void OnImage(const lcm::ReceiveBuffer*, const std::string& channel, const aglcm::image_t* m) {
      channels.push_back(channel);
      t_ns.push_back(m->t_ns);
    }
    void OnOdometry(const lcm::ReceiveBuffer*, const std::string& channel,
                    const aglcm::odometry_t* m) {
      channels.push_back(channel);
      t_ns.push_back(m->t_ns);
    }
    void OnPoints(const lcm::ReceiveBuffer*, const std::string& channel,
                  const aglcm::point_cloud_t* m) {
      channels.push_back(channel);
      t_ns.push_back(m->t_ns);
    }
  } receiver;
  lcm.subscribe("AG_UGV_IMAGE|AG_AIR_IMAGE_.*", &Receiver::OnImage, &receiver);
  lcm.subscribe("AG_UGV_ODOMETRY|AG_AIR_ODOMETRY_.*", &Receiver::OnOdometry, &receiver);
  lcm.subscribe(kUgvPointsChannel, &Receiver::OnPoints, &receiver);
  DatasetPlayer player(dataset_, Fast());
  std::atomic<bool> stop{false};
  player.Run(
      [&](const std::string& channel, const std::vector<uint8_t>& bytes) {
        const bool ok =
            lcm.publish(channel, bytes.data(), static_cast<unsigned int>(bytes.size())) == 0;
        // Deliver now: a subscription queues at most 30 messages.
        for (int i = 0; i < 10 && lcm.handleTimeout(0) > 0; ++i) {
        }
        return ok;
      },
      stop);
  const auto& s = player.schedule();
  ASSERT_EQ(receiver.channels.size(), s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(receiver.channels[i], ChannelOf(s[i]));
    EXPECT_EQ(receiver.t_ns[i], s[i].t_ns);
  }
}

TEST(PacerTest, TimelineScaledBySpeedAndRateLimits) {
  using Clock = Pacer::Clock;
  const Clock::time_point start{};
  const auto ms = [](double v) {
    return std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double, std::milli>(v));
  };
  DatasetPlayerOptions o;
  o.speed = 2;
  o.max_rate_hz = 0;
  o.max_mbps = 0;
  Pacer timeline(o, start, 1000000000);
  EXPECT_EQ(timeline.Due(1000000000), start);
  EXPECT_EQ(timeline.Due(1500000000), start + ms(250)) << "0.5 s of data at x2";
  timeline.Published(start + ms(300), 1000000);
  EXPECT_EQ(timeline.Due(1500000000), start + ms(300)) << "never before the previous message";
  EXPECT_EQ(timeline.Due(2000000000), start + ms(500));

  o.speed = 0;
  o.max_rate_hz = 100;  // 10 ms apart
  o.max_mbps = 8;       // 1 byte per microsecond
  Pacer limited(o, start, 0);
  EXPECT_EQ(limited.Due(5000000000), start) << "speed 0: no timeline";
  limited.Published(start, 100);
  EXPECT_EQ(limited.Due(0), start + ms(10)) << "small message: the message rate limits";
  limited.Published(start + ms(10), 50000);
  EXPECT_EQ(limited.Due(0), start + ms(60)) << "50 kB at 8 Mbit/s take 50 ms";

  o.speed = 1;
  Pacer both(o, start, 0);
  both.Published(start, 100);
  EXPECT_EQ(both.Due(1000000), start + ms(10)) << "the later of timeline and limits";
  EXPECT_EQ(both.Due(30000000), start + ms(30));
}

TEST_F(DatasetPlayerTest, RealTimePlaybackTakesTheDataTime) {
  DatasetPlayerOptions o;  // speed 1, default limits
  o.duration_s = 0.3;
  o.odometry_margin_s = 0;
  DatasetPlayer player(dataset_, o);
  DatasetPlayerStats stats;
  PlayToVector(player, &stats);
  EXPECT_EQ(stats.messages, stats.scheduled);
  EXPECT_NEAR(stats.data_s, 0.3, 1e-9);
  EXPECT_GE(stats.wall_s, 0.3 - 0.005) << "paced by the timeline, not faster";
}

TEST_F(DatasetPlayerTest, StopEndsTheRunEarly) {
  DatasetPlayer player(dataset_, Fast());
  std::atomic<bool> stop{false};
  int published = 0;
  const DatasetPlayerStats stats = player.Run(
      [&](const std::string&, const std::vector<uint8_t>&) {
        if (++published == 5) stop = true;
        return true;
      },
      stop);
  EXPECT_EQ(published, 5);
  EXPECT_EQ(stats.messages, 5);
  EXPECT_TRUE(stats.stopped);
  EXPECT_NE(FormatSummary(stats).find("stopped before the end"), std::string::npos);
}

TEST_F(DatasetPlayerTest, UnreadableImageStopsWithTheFileNamed) {
  const SensorFrame& victim = dataset_.air.at("uav1").images[3];
  fs::remove(victim.path);
  std::ofstream(victim.path) << "not a png";
  DatasetPlayer player(dataset_, Fast());
  std::atomic<bool> stop{false};
  int published = 0;
  try {
    player.Run(
        [&](const std::string&, const std::vector<uint8_t>&) {
          ++published;
          return true;
        },
        stop);
    FAIL() << "a broken image must not be skipped silently";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(victim.filename), std::string::npos) << e.what();
  }
  EXPECT_GT(published, 0) << "what came before the broken file was played";
}

TEST_F(DatasetPlayerTest, PublishFailuresAreCounted) {
  DatasetPlayer player(dataset_, Fast());
  std::atomic<bool> stop{false};
  const DatasetPlayerStats stats =
      player.Run([](const std::string&, const std::vector<uint8_t>&) { return false; }, stop);
  EXPECT_EQ(stats.publish_errors, stats.scheduled);
  EXPECT_NE(FormatSummary(stats).find("failed to publish"), std::string::npos);
}

}  // namespace
}  // namespace ag
