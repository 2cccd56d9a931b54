#pragma once

// The dataset player (tools/play_dataset): publishes the sensor streams of a
// dataset (../shared/spec/dataset.md) on the LCM channels the daemons read,
// merged in time order, so air_agent (live mode) and ground_server run on
// recorded or simulated data exactly as on the vehicles:
//
//   ground/images      -> AG_UGV_IMAGE              image_t (PNG), frame_id camera_frame_id
//   ground/odometry    -> AG_UGV_ODOMETRY           odometry_t T_wg_body
//   ground/scans       -> AG_UGV_POINTS             point_cloud_t, LiDAR frame
//   air/<a>/images     -> AG_AIR_IMAGE_<a>          image_t (PNG), frame_id camera_frame_id
//   air/<a>/odometry   -> AG_AIR_ODOMETRY_<a>       odometry_t T_wa_body
//
// Every message keeps the timestamp of the dataset (each agent's own clock);
// only the wall-clock pacing is the player's. Building the schedule and
// encoding a message are plain functions that tests call without threads or
// LCM; DatasetPlayer::Run adds a loader thread (bounded queue) and the
// pacing, and publishes through a sink (LCM in tools/play_dataset).

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "common/dataset/dataset.h"
#include "common/logging/logging.h"

namespace ag {

struct DatasetPlayerOptions {
  std::string lcm_url;  ///< LCM provider URL; empty: LCM's default / $LCM_DEFAULT_URL
  /// Wall-clock pacing: 1 = real time, 2 = twice as fast; 0 = no timeline
  /// pacing (as fast as the rate limits below allow).
  double speed = 1.0;
  /// Upper bound on messages per second, in every mode (0: none). UDP
  /// receivers drop what they cannot queue: an LCM subscription queues 30
  /// messages by default, so a daemon busy for 100 ms on a keyframe must not
  /// be sent more than that meanwhile.
  double max_rate_hz = 500.0;
  /// Upper bound on the LCM payload rate (Mbit/s), in every mode (0: none).
  /// Spaces out large messages (images, scans) so the receivers' socket
  /// buffers drain between them.
  double max_mbps = 400.0;
  std::vector<std::string> agents;  ///< air agents to play; empty: all of the dataset
  bool ground = true;               ///< play the ground agent's streams
  bool air = true;                  ///< play the air agents' streams
  double start_s = 0.0;             ///< skip this much from the start of the merged timeline (s)
  double duration_s = 0.0;          ///< play this long from start_s (s); 0: to the end
  /// With start_s / duration_s: odometry is also played this far before the
  /// window and after it, so the first and last images and scans of the
  /// window can be interpolated (s).
  double odometry_margin_s = 0.2;
  /// Shift each air agent's timeline so its first message plays together
  /// with the ground's first: for agents whose clocks are far apart (e.g.
  /// EuRoC imported next to KITTI). Message timestamps stay unchanged.
  bool align_starts = false;
  std::string camera_frame_id = "cam0";  ///< image_t.frame_id (air_agent's frontend.camera_id)
  std::string lidar_frame_id = "lidar";  ///< point_cloud_t.frame_id
  std::string body_frame_id = "body";    ///< odometry_t.body_frame_id
  int queue_messages = 64;               ///< messages loaded and encoded ahead of time
  double progress_period_s = 5.0;        ///< progress log line period (s)
  LoggingOptions logging;

  template <class V>
  void VisitFields(V& v) {
    v("lcm_url", lcm_url);
    v("speed", speed);
    v("max_rate_hz", max_rate_hz);
    v("max_mbps", max_mbps);
    v("agents", agents);
    v("ground", ground);
    v("air", air);
    v("start_s", start_s);
    v("duration_s", duration_s);
    v("odometry_margin_s", odometry_margin_s);
    v("align_starts", align_starts);
    v("camera_frame_id", camera_frame_id);
    v("lidar_frame_id", lidar_frame_id);
    v("body_frame_id", body_frame_id);
    v("queue_messages", queue_messages);
    v("progress_period_s", progress_period_s);
    v("logging", logging);
  }
  void Check() const;
};

/// The five kinds of stream, in the order messages of equal time are played:
/// odometry first, so a receiver has the pose when the image or scan of the
/// same instant arrives.
enum class StreamKind { kGroundOdometry, kAirOdometry, kGroundScan, kGroundImage, kAirImage };

/// One message of the merged timeline.
struct ScheduledMessage {
  int64_t play_t_ns = 0;  ///< position on the merged timeline (t_ns unless align_starts)
  int64_t t_ns = 0;       ///< the dataset timestamp the message carries
  StreamKind kind = StreamKind::kGroundOdometry;
  std::string agent;  ///< "ground" or the air agent
  size_t index = 0;   ///< row in the agent's images / scans / odometry
};

/// The channel a scheduled message goes to (common/wire/channels.h).
std::string ChannelOf(const ScheduledMessage& message);

/// The merged timeline: the selected streams, sorted by play time (ties:
/// StreamKind order, then agent name), cut to [start_s, start_s +
/// duration_s] from the first message (odometry: widened by
/// odometry_margin_s). Throws OptionError for an air agent the dataset does
/// not have (naming the ones it has) or when nothing is selected.
std::vector<ScheduledMessage> BuildSchedule(const Dataset& dataset,
                                            const DatasetPlayerOptions& options);

/// One message ready to publish.
struct EncodedMessage {
  std::string channel;
  int64_t play_t_ns = 0;
  std::vector<uint8_t> bytes;  ///< the LCM-encoded message
};

/// Loads (image, PCD) and encodes one scheduled message. Throws InputError
/// naming the file when an image or scan cannot be read.
EncodedMessage EncodeScheduled(const Dataset& dataset, const ScheduledMessage& message,
                               const DatasetPlayerOptions& options);

/// When each message may go: the timeline (speed > 0) and the rate limits.
/// Plain arithmetic on time points, so tests drive it with a fake clock.
class Pacer {
 public:
  using Clock = std::chrono::steady_clock;
  Pacer(const DatasetPlayerOptions& options, Clock::time_point start, int64_t first_play_t_ns);
  /// Earliest time the message at play_t_ns may be published.
  Clock::time_point Due(int64_t play_t_ns) const;
  /// Records a message of `bytes` published at `when` (for the rate limits).
  void Published(Clock::time_point when, size_t bytes);
  /// The timeline's due time alone (speed > 0), for lateness.
  Clock::time_point TimelineDue(int64_t play_t_ns) const;

 private:
  double speed_;
  double max_rate_hz_;
  double max_mbps_;
  Clock::time_point start_;
  int64_t first_play_t_ns_;
  Clock::time_point next_allowed_;
};

/// What a run published.
struct ChannelStats {
  int64_t messages = 0;
  int64_t bytes = 0;  ///< LCM message bytes (without LCM/UDP headers)
};
struct DatasetPlayerStats {
  std::map<std::string, ChannelStats> channels;
  int64_t messages = 0;
  int64_t bytes = 0;
  int64_t scheduled = 0;       ///< messages in the schedule
  int64_t publish_errors = 0;  ///< the sink reported failure
  int64_t late_messages = 0;   ///< speed > 0: published > 50 ms after their time
  double max_late_s = 0;       ///< the worst of those
  double wall_s = 0;           ///< from the first to the last message
  double data_s = 0;           ///< timeline covered by the published messages
  bool stopped = false;        ///< ended by `stop`, not by the end of the schedule
};

/// The summary table tools/play_dataset prints: per channel messages and
/// bytes, totals, wall and data time.
std::string FormatSummary(const DatasetPlayerStats& stats);

class DatasetPlayer {
 public:
  /// Publishes one encoded message; returns false when it failed.
  using Sink = std::function<bool(const std::string& channel, const std::vector<uint8_t>& bytes)>;

  /// Builds the schedule (throws as BuildSchedule). `dataset` must outlive
  /// the player.
  DatasetPlayer(const Dataset& dataset, const DatasetPlayerOptions& options);

  const std::vector<ScheduledMessage>& schedule() const { return schedule_; }

  /// Plays the schedule through `sink` until its end or `stop`. A loader
  /// thread reads and encodes up to queue_messages ahead. Rethrows a loading
  /// error (after stopping the loader). Logs progress every
  /// progress_period_s.
  DatasetPlayerStats Run(const Sink& sink, const std::atomic<bool>& stop);

 private:
  const Dataset& dataset_;
  DatasetPlayerOptions options_;
  std::vector<ScheduledMessage> schedule_;
};

}  // namespace ag
