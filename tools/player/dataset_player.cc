#include "tools/player/dataset_player.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <exception>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <tuple>

#include "common/core/error.h"
#include "common/pcd/pcd_io.h"
#include "common/wire/channels.h"
#include "common/wire/message_codec.h"

namespace ag {
namespace {

using Clock = Pacer::Clock;

constexpr int64_t kLateThresholdNs = 50000000;  // 50 ms behind the timeline counts as late

int64_t SecondsToNs(double s) { return static_cast<int64_t>(std::llround(s * 1e9)); }

template <class Message>
std::vector<uint8_t> EncodeLcm(const Message& message) {
  std::vector<uint8_t> bytes(static_cast<size_t>(message.getEncodedSize()));
  message.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

bool IsOdometry(StreamKind kind) {
  return kind == StreamKind::kGroundOdometry || kind == StreamKind::kAirOdometry;
}

/// First timestamp of any stream of an agent.
int64_t FirstTime(const AgentData& agent) {
  int64_t t = std::numeric_limits<int64_t>::max();
  if (!agent.images.empty()) t = std::min(t, agent.images.front().t_ns);
  if (!agent.scans.empty()) t = std::min(t, agent.scans.front().t_ns);
  if (!agent.odometry.empty()) t = std::min(t, agent.odometry.front().t_ns);
  return t;
}

void AddAgent(const AgentData& agent, bool ground, int64_t shift_ns,
              std::vector<ScheduledMessage>* out) {
  auto add = [&](StreamKind kind, int64_t t_ns, size_t index) {
    ScheduledMessage m;
    m.play_t_ns = t_ns - shift_ns;
    m.t_ns = t_ns;
    m.kind = kind;
    m.agent = agent.name;
    m.index = index;
    out->push_back(std::move(m));
  };
  for (size_t i = 0; i < agent.odometry.size(); ++i) {
    add(ground ? StreamKind::kGroundOdometry : StreamKind::kAirOdometry, agent.odometry[i].t_ns, i);
  }
  for (size_t i = 0; i < agent.images.size(); ++i) {
    add(ground ? StreamKind::kGroundImage : StreamKind::kAirImage, agent.images[i].t_ns, i);
  }
  if (ground) {
    for (size_t i = 0; i < agent.scans.size(); ++i) {
      add(StreamKind::kGroundScan, agent.scans[i].t_ns, i);
    }
  }
}

const AgentData& AgentOf(const Dataset& dataset, const ScheduledMessage& message) {
  if (message.agent == "ground") return dataset.ground;
  const auto it = dataset.air.find(message.agent);
  if (it == dataset.air.end()) {
    throw std::invalid_argument("dataset has no air agent '" + message.agent + "'");
  }
  return it->second;
}

std::string FormatBytes(int64_t bytes) {
  if (bytes >= 1000000) return fmt::format("{:.1f} MB", static_cast<double>(bytes) / 1e6);
  if (bytes >= 1000) return fmt::format("{:.1f} kB", static_cast<double>(bytes) / 1e3);
  return fmt::format("{} B", bytes);
}

}  // namespace

void DatasetPlayerOptions::Check() const {
  CheckOption(speed >= 0 && std::isfinite(speed), "speed", "must be >= 0 (0: as fast as allowed)");
  CheckOption(max_rate_hz >= 0, "max_rate_hz", "must be >= 0 (0: no limit)");
  CheckOption(max_mbps >= 0, "max_mbps", "must be >= 0 (0: no limit)");
  CheckOption(ground || air, "ground", "and air are both off: nothing to play");
  CheckOption(air || agents.empty(), "agents", "selects air agents, but air is off");
  for (const std::string& agent : agents) {
    CheckOption(IsValidAgentName(agent), "agents", "'" + agent + "' is not [a-z0-9_]+");
  }
  CheckOption(start_s >= 0, "start_s", "must be >= 0");
  CheckOption(duration_s >= 0, "duration_s", "must be >= 0 (0: to the end)");
  CheckOption(odometry_margin_s >= 0, "odometry_margin_s", "must be >= 0");
  CheckOption(!camera_frame_id.empty(), "camera_frame_id", "must not be empty");
  CheckOption(!lidar_frame_id.empty(), "lidar_frame_id", "must not be empty");
  CheckOption(!body_frame_id.empty(), "body_frame_id", "must not be empty");
  CheckOption(queue_messages >= 1, "queue_messages", "must be >= 1");
  CheckOption(progress_period_s > 0, "progress_period_s", "must be > 0");
}

std::string ChannelOf(const ScheduledMessage& message) {
  switch (message.kind) {
    case StreamKind::kGroundOdometry:
      return kUgvOdometryChannel;
    case StreamKind::kGroundScan:
      return kUgvPointsChannel;
    case StreamKind::kGroundImage:
      return kUgvImageChannel;
    case StreamKind::kAirOdometry:
      return AirOdometryChannel(message.agent);
    case StreamKind::kAirImage:
      return AirImageChannel(message.agent);
  }
  return "";
}

std::vector<ScheduledMessage> BuildSchedule(const Dataset& dataset,
                                            const DatasetPlayerOptions& options) {
  options.Check();
  std::vector<const AgentData*> air;
  if (options.air) {
    std::string names;
    for (const auto& [name, _] : dataset.air) names += (names.empty() ? "" : ", ") + name;
    if (options.agents.empty()) {
      for (const auto& [name, agent] : dataset.air) air.push_back(&agent);
    }
    for (const std::string& name : options.agents) {
      const auto it = dataset.air.find(name);
      if (it == dataset.air.end()) {
        throw OptionError("agents", "'" + name + "' is not an air agent of dataset " + dataset.dir +
                                        " (it has: " + (names.empty() ? "none" : names) + ")");
      }
      if (std::find(air.begin(), air.end(), &it->second) == air.end()) air.push_back(&it->second);
    }
  }
  if (!options.ground && air.empty()) {
    throw OptionError("air", "selects no air agent (dataset " + dataset.dir +
                                 " has none) and the ground is off: nothing to play");
  }

  const int64_t ground_start = FirstTime(dataset.ground);
  std::vector<ScheduledMessage> all;
  if (options.ground) AddAgent(dataset.ground, true, 0, &all);
  for (const AgentData* agent : air) {
    const int64_t offset = FirstTime(*agent) - ground_start;
    if (!options.align_starts && std::abs(offset) > SecondsToNs(60)) {
      spdlog::warn(
          "air agent '{}' starts {:.1f} s from the ground in its own clock: played on one "
          "timeline, the gap is waited out; --align-starts plays both from the start",
          agent->name, 1e-9 * static_cast<double>(offset));
    }
    AddAgent(*agent, false, options.align_starts ? offset : 0, &all);
  }
  std::stable_sort(all.begin(), all.end(),
                   [](const ScheduledMessage& a, const ScheduledMessage& b) {
                     return std::tie(a.play_t_ns, a.kind, a.agent, a.index) <
                            std::tie(b.play_t_ns, b.kind, b.agent, b.index);
                   });
  if (all.empty()) return all;

  const int64_t window_start = all.front().play_t_ns + SecondsToNs(options.start_s);
  const int64_t window_end = options.duration_s > 0 ? window_start + SecondsToNs(options.duration_s)
                                                    : std::numeric_limits<int64_t>::max();
  const int64_t margin = SecondsToNs(options.odometry_margin_s);
  std::vector<ScheduledMessage> out;
  bool any_in_window = false;
  for (ScheduledMessage& m : all) {
    const bool in_window = m.play_t_ns >= window_start && m.play_t_ns <= window_end;
    const bool in_margin =
        IsOdometry(m.kind) && m.play_t_ns >= window_start - margin &&
        (window_end == std::numeric_limits<int64_t>::max() || m.play_t_ns <= window_end + margin);
    any_in_window = any_in_window || in_window;
    if (in_window || in_margin) out.push_back(std::move(m));
  }
  if (!any_in_window) {
    throw OptionError("start_s",
                      fmt::format("{} s is past the end of the selected data", options.start_s));
  }
  return out;
}

EncodedMessage EncodeScheduled(const Dataset& dataset, const ScheduledMessage& message,
                               const DatasetPlayerOptions& options) {
  const AgentData& agent = AgentOf(dataset, message);
  EncodedMessage out;
  out.channel = ChannelOf(message);
  out.play_t_ns = message.play_t_ns;
  switch (message.kind) {
    case StreamKind::kGroundOdometry:
    case StreamKind::kAirOdometry:
      out.bytes = EncodeLcm(EncodeOdometry(
          agent.odometry.at(message.index),
          message.kind == StreamKind::kGroundOdometry ? "wg" : "wa", options.body_frame_id));
      break;
    case StreamKind::kGroundImage:
    case StreamKind::kAirImage: {
      const SensorFrame& frame = agent.images.at(message.index);
      out.bytes = EncodeLcm(EncodeImagePng(frame.t_ns, options.camera_frame_id,
                                           LoadImage(frame, cv::IMREAD_UNCHANGED)));
      break;
    }
    case StreamKind::kGroundScan: {
      const SensorFrame& frame = agent.scans.at(message.index);
      const PointCloud cloud = ReadScan(frame.path);
      out.bytes = EncodeLcm(
          EncodePointCloud(frame.t_ns, options.lidar_frame_id, cloud.points, cloud.intensity));
      break;
    }
  }
  return out;
}

Pacer::Pacer(const DatasetPlayerOptions& options, Clock::time_point start, int64_t first_play_t_ns)
    : speed_(options.speed),
      max_rate_hz_(options.max_rate_hz),
      max_mbps_(options.max_mbps),
      start_(start),
      first_play_t_ns_(first_play_t_ns),
      next_allowed_(start) {}

Clock::time_point Pacer::TimelineDue(int64_t play_t_ns) const {
  if (speed_ <= 0) return start_;
  return start_ + std::chrono::nanoseconds(static_cast<int64_t>(
                      static_cast<double>(play_t_ns - first_play_t_ns_) / speed_));
}

Clock::time_point Pacer::Due(int64_t play_t_ns) const {
  return std::max(TimelineDue(play_t_ns), next_allowed_);
}

void Pacer::Published(Clock::time_point when, size_t bytes) {
  double gap_s = 0;
  if (max_rate_hz_ > 0) gap_s = std::max(gap_s, 1.0 / max_rate_hz_);
  if (max_mbps_ > 0) gap_s = std::max(gap_s, static_cast<double>(bytes) * 8.0 / (max_mbps_ * 1e6));
  next_allowed_ = when + std::chrono::nanoseconds(static_cast<int64_t>(gap_s * 1e9));
}

std::string FormatSummary(const DatasetPlayerStats& stats) {
  std::string out = fmt::format(
      "play_dataset: {} of {} messages, {} bytes ({}) in {:.2f} s; data time {:.2f} s{}\n",
      stats.messages, stats.scheduled, stats.bytes, FormatBytes(stats.bytes), stats.wall_s,
      stats.data_s,
      stats.wall_s > 0 && stats.data_s > 0 ? fmt::format(" (x{:.2f})", stats.data_s / stats.wall_s)
                                           : "");
  out += fmt::format("  {:<32} {:>10} {:>14}\n", "channel", "messages", "bytes");
  for (const auto& [channel, c] : stats.channels) {
    out += fmt::format("  {:<32} {:>10} {:>14}\n", channel, c.messages, c.bytes);
  }
  if (stats.late_messages > 0) {
    out += fmt::format(
        "  {} messages more than 50 ms behind the timeline (worst {:.3f} s): loading or the "
        "rate limits could not keep up\n",
        stats.late_messages, stats.max_late_s);
  }
  if (stats.publish_errors > 0) {
    out += fmt::format("  {} messages failed to publish\n", stats.publish_errors);
  }
  if (stats.stopped) out += "  stopped before the end\n";
  return out;
}

DatasetPlayer::DatasetPlayer(const Dataset& dataset, const DatasetPlayerOptions& options)
    : dataset_(dataset), options_(options), schedule_(BuildSchedule(dataset, options)) {}

DatasetPlayerStats DatasetPlayer::Run(const Sink& sink, const std::atomic<bool>& stop) {
  DatasetPlayerStats stats;
  stats.scheduled = static_cast<int64_t>(schedule_.size());
  if (schedule_.empty()) return stats;

  // Loader thread -> bounded queue -> this thread (pacing, publishing).
  std::mutex mutex;
  std::condition_variable cv;
  std::deque<EncodedMessage> queue;
  bool loader_done = false;
  std::exception_ptr loader_error;
  std::atomic<bool> abort{false};
  const size_t capacity = static_cast<size_t>(options_.queue_messages);
  std::thread loader([&] {
    try {
      for (const ScheduledMessage& m : schedule_) {
        if (stop || abort) break;
        EncodedMessage encoded = EncodeScheduled(dataset_, m, options_);
        std::unique_lock<std::mutex> lock(mutex);
        while (queue.size() >= capacity && !stop && !abort) {
          cv.wait_for(lock, std::chrono::milliseconds(100));
        }
        if (stop || abort) break;
        queue.push_back(std::move(encoded));
        cv.notify_all();
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      loader_error = std::current_exception();
    }
    std::lock_guard<std::mutex> lock(mutex);
    loader_done = true;
    cv.notify_all();
  });

  const auto wait_slice = std::chrono::milliseconds(50);
  // Let the loader get ahead before the clock starts (bounded: 2 s), so the
  // first seconds are not played late.
  {
    std::unique_lock<std::mutex> lock(mutex);
    const auto deadline = Clock::now() + std::chrono::seconds(2);
    while (!stop && !loader_done && queue.size() < capacity && Clock::now() < deadline) {
      cv.wait_for(lock, wait_slice);
    }
  }

  const auto start = Clock::now();
  Pacer pacer(options_, start, schedule_.front().play_t_ns);
  auto last_progress = start;
  std::optional<int64_t> first_played, last_played;
  std::optional<Clock::time_point> last_publish;
  const double total_data_s =
      1e-9 * static_cast<double>(schedule_.back().play_t_ns - schedule_.front().play_t_ns);
  while (!stop) {
    EncodedMessage m;
    {
      std::unique_lock<std::mutex> lock(mutex);
      while (queue.empty() && !loader_done && !stop) cv.wait_for(lock, wait_slice);
      if (queue.empty()) break;  // loader done (or failed), or stop
      m = std::move(queue.front());
      queue.pop_front();
      cv.notify_all();
    }
    const auto due = pacer.Due(m.play_t_ns);
    for (auto now = Clock::now(); now < due && !stop; now = Clock::now()) {
      std::this_thread::sleep_for(std::min<Clock::duration>(due - now, wait_slice));
    }
    if (stop) break;
    const auto before = Clock::now();
    if (options_.speed > 0) {
      const int64_t late_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                  before - pacer.TimelineDue(m.play_t_ns))
                                  .count();
      if (late_ns > kLateThresholdNs) {
        ++stats.late_messages;
        stats.max_late_s = std::max(stats.max_late_s, 1e-9 * static_cast<double>(late_ns));
      }
    }
    if (!sink(m.channel, m.bytes)) ++stats.publish_errors;
    const auto after = Clock::now();
    pacer.Published(after, m.bytes.size());
    last_publish = after;
    ChannelStats& c = stats.channels[m.channel];
    ++c.messages;
    c.bytes += static_cast<int64_t>(m.bytes.size());
    ++stats.messages;
    stats.bytes += static_cast<int64_t>(m.bytes.size());
    if (!first_played) first_played = m.play_t_ns;
    last_played = m.play_t_ns;
    if (std::chrono::duration<double>(after - last_progress).count() >=
        options_.progress_period_s) {
      spdlog::info("played {}/{} messages, {:.1f} of {:.1f} s of data, {}", stats.messages,
                   stats.scheduled, 1e-9 * static_cast<double>(*last_played - *first_played),
                   total_data_s, FormatBytes(stats.bytes));
      last_progress = after;
    }
  }
  abort = true;
  cv.notify_all();
  loader.join();
  if (loader_error) std::rethrow_exception(loader_error);
  stats.stopped = stats.messages < stats.scheduled;
  if (last_publish) stats.wall_s = std::chrono::duration<double>(*last_publish - start).count();
  if (first_played) stats.data_s = 1e-9 * static_cast<double>(*last_played - *first_played);
  return stats;
}

}  // namespace ag
