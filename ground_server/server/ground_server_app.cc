#include "ground_server/server/ground_server_app.h"

#include <spdlog/fmt/ranges.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <thread>

#include "common/config/options.h"
#include "common/core/agent_name.h"
#include "common/dataset/dataset.h"
#include "common/wire/channels.h"
#include "common/wire/keyframe_assembler.h"
#include "common/wire/keyframe_codec.h"
#include "common/wire/lcm_url.h"
#include "common/wire/link_bytes.h"
#include "common/wire/message_codec.h"
#include "ground_server/matching/blas_info.h"
#include "lcmtypes/checked_decode.h"

namespace ag {

namespace fs = std::filesystem;
using SteadyClock = std::chrono::steady_clock;

namespace {

/// A steady-clock time in seconds, the KeyframeAssembler's clock.
double SteadySeconds(SteadyClock::time_point t) {
  return std::chrono::duration<double>(t.time_since_epoch()).count();
}

double SecondsSince(SteadyClock::time_point t) {
  return std::chrono::duration<double>(SteadyClock::now() - t).count();
}

int64_t Nanoseconds(double seconds) { return static_cast<int64_t>(std::llround(seconds * 1e9)); }

/// Trailing window of the per-agent link rate in the status line (s).
constexpr double kLinkWindowS = 10.0;

/// Width and height in a PNG's IHDR chunk (the first chunk, bytes 16..23),
/// so an image can be checked against its message before it is decoded (a
/// small PNG may declare a huge image: decoding it would allocate that).
bool PngSize(const std::vector<uint8_t>& data, int64_t* width, int64_t* height) {
  static const uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (data.size() < 24 || !std::equal(kSignature, kSignature + 8, data.begin()) ||
      std::string(data.begin() + 12, data.begin() + 16) != "IHDR") {
    return false;
  }
  auto be32 = [&](size_t at) {
    return (int64_t{data[at]} << 24) | (int64_t{data[at + 1]} << 16) |
           (int64_t{data[at + 2]} << 8) | int64_t{data[at + 3]};
  };
  *width = be32(16);
  *height = be32(20);
  return true;
}

/// Cheap checks of a UGV image before it is queued (the full decoding runs
/// on the frontend thread): "" when it may be a valid image.
std::string ImageProblem(const aglcm::image_t& m) {
  if (m.num_bytes != static_cast<int>(m.data.size())) return "num_bytes mismatch";
  if (m.width <= 0 || m.height <= 0 || m.width > 16384 || m.height > 16384) {
    return "implausible size " + std::to_string(m.width) + "x" + std::to_string(m.height);
  }
  if (m.encoding == "png") {
    int64_t w = 0, h = 0;
    if (!PngSize(m.data, &w, &h)) return "png data without a PNG header";
    if (w != m.width || h != m.height) {
      return "png is " + std::to_string(w) + "x" + std::to_string(h) + ", message says " +
             std::to_string(m.width) + "x" + std::to_string(m.height);
    }
    return "";
  }
  if (m.encoding == "jpeg") return "";
  int channels = 0;
  if (m.encoding == "mono8") {
    channels = 1;
  } else if (m.encoding == "bgr8" || m.encoding == "rgb8") {
    channels = 3;
  } else {
    return "unknown encoding '" + m.encoding + "'";
  }
  if (m.step < m.width * channels ||
      static_cast<int64_t>(m.step) * m.height > static_cast<int64_t>(m.data.size())) {
    return "step/size do not fit the data";
  }
  return "";
}

/// Hex text of bytes and back, for the LCM-encoded camera infos in state.yaml.
std::string ToHex(const std::vector<uint8_t>& bytes) {
  static const char* kHex = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * bytes.size());
  for (uint8_t b : bytes) {
    hex += kHex[b >> 4];
    hex += kHex[b & 15];
  }
  return hex;
}
bool FromHex(const std::string& hex, std::vector<uint8_t>* bytes) {
  if (hex.size() % 2 != 0) return false;
  bytes->resize(hex.size() / 2);
  for (size_t i = 0; i < bytes->size(); ++i) {
    int value = 0;
    for (int k = 0; k < 2; ++k) {
      const char c = hex[2 * i + k];
      const int digit = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
      if (digit < 0) return false;
      value = 16 * value + digit;
    }
    (*bytes)[i] = static_cast<uint8_t>(value);
  }
  return true;
}

/// Whether two camera_infos describe the same camera (send times aside).
bool SameCamera(aglcm::camera_info_t a, aglcm::camera_info_t b) {
  a.t_ns = b.t_ns = 0;
  std::vector<uint8_t> ea(a.getEncodedSize()), eb(b.getEncodedSize());
  a.encode(ea.data(), 0, static_cast<int>(ea.size()));
  b.encode(eb.data(), 0, static_cast<int>(eb.size()));
  return ea == eb;
}

}  // namespace

void GroundServerOptions::Check() const {
  CheckOption(lcm_recv_buf_bytes >= 0, "lcm_recv_buf_bytes", "must be >= 0");
  CheckOption(lcm_min_recv_buf_bytes >= 0, "lcm_min_recv_buf_bytes", "must be >= 0");
  CheckOption(!calibration_file.empty(), "calibration_file",
              "is required (the UGV's calibration.yaml in the dataset format)");
  CheckOption(save_period_s > 0, "save_period_s", "must be > 0");
  CheckOption(ugv_keyframe_period_s > 0, "ugv_keyframe_period_s", "must be > 0");
  CheckOption(window_size >= 1, "window_size", "must be >= 1");
  CheckOption(estimate_period_s > 0, "estimate_period_s", "must be > 0");
  CheckOption(image_queue >= 1, "image_queue", "must be >= 1");
  CheckOption(pending_sensor_queue >= 1, "pending_sensor_queue", "must be >= 1");
  CheckOption(air_keyframe_queue >= 1, "air_keyframe_queue", "must be >= 1");
  CheckOption(air_part_timeout_s > 0, "air_part_timeout_s", "must be > 0");
  CheckOption(odometry_queue_messages >= 1, "odometry_queue_messages", "must be >= 1");
  CheckOption(max_air_agents >= 1, "max_air_agents", "must be >= 1");
  std::string regex_error;
  try {
    std::regex(air_agents, std::regex::extended);
  } catch (const std::regex_error& e) {
    regex_error = e.what();
  }
  CheckOption(!air_agents.empty() && regex_error.empty(), "air_agents",
              "must be a POSIX extended regular expression over agent names; got '" + air_agents +
                  "'" + (regex_error.empty() ? "" : " (" + regex_error + ")"));
  CheckOption(clock_jump_s > 0, "clock_jump_s", "must be > 0");
  CheckOption(clock_jump_confirmations >= 1, "clock_jump_confirmations", "must be >= 1");
  CheckOption(stats_period_s > 0, "stats_period_s", "must be > 0");
}

/// One air agent's camera, as received and as the estimator uses it.
struct AirCamera {
  aglcm::camera_info_t message;  // for persistence
  std::shared_ptr<const Camera> camera;
};

/// Everything the daemon knows about one air agent.
struct AgentState {
  std::string name;
  std::thread thread;
  // Used by the agent's estimation thread only (no lock).
  std::unique_ptr<AgentEstimator> estimator;
  uint64_t applied_cameras = 0;  // camera_version applied to the estimator
  uint64_t applied_reset = 0;    // reset_generation the estimator was made at
  int64_t out_seq = 0;           // relative_pose_t sequence

  // Set by the keyframe thread, read by the estimation thread: a stored
  // keyframe wakes the estimation (see AgentLoop).
  std::atomic<uint64_t> keyframe_generation{0};
  std::atomic<int64_t> newest_keyframe_t_ns{0};
  std::atomic<int64_t> newest_keyframe_arrival_ns{0};  // steady clock

  // Guarded by `mutex`, which is never held during an estimate, so the LCM
  // and keyframe threads never wait for one.
  std::mutex mutex;
  std::map<std::string, AirCamera> cameras;  // by camera_id
  uint64_t camera_version = 0;               // bumped when `cameras` changes
  uint64_t reset_generation = 0;             // bumped by a UGV clock jump
  // Link and keyframes.
  std::deque<std::pair<SteadyClock::time_point, int64_t>> recent_ip_bytes;
  std::map<int64_t, SteadyClock::time_point> received;  // air t_ns -> arrival, for latency
  int64_t packets = 0;
  int64_t stored = 0;
  int64_t rejected = 0;
  int64_t seq_gaps = 0;
  int64_t parts_lost = 0;               // parts of split keyframes that never arrived
  std::optional<int64_t> last_raw_seq;  // as the UAV numbered it
  int64_t seq_offset = 0;               // added to the UAV's seq (after a UAV restart)
  int64_t max_stored_seq = -1;          // in the place database (restored ones included)
  // Last estimate, for the status line.
  std::string status = "initializing";
  std::string reason = "no estimate yet";
  int inliers = 0;
  double latency_s = -1;
  bool has_covariance = false;
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  std::optional<Pose> fix;
  int64_t estimates = 0;
};

struct GroundServerApp::Impl {
  GroundServerOptions options;
  AgentCalibration calibration;
  std::unique_ptr<lcm::LCM> owned_lcm;
  lcm::LCM* lcm = nullptr;
  std::vector<lcm::Subscription*> subscriptions;
  std::unique_ptr<FeatureExtractor> features;
  std::unique_ptr<GlobalDescriptorExtractor> global;
  std::unique_ptr<UgvFrontend> frontend;
  VoxelMap map;
  VoxelMapBuilder builder;
  PlaceDb db;
  PlaceDbSource source{&db};

  // The odometry buffer, replaced on a clock jump: the LCM thread owns the
  // pointer; the frontend thread takes a copy under the mutex.
  mutable std::mutex odometry_mutex;
  std::shared_ptr<OdometryBuffer> odometry;
  std::atomic<uint64_t> ugv_epoch{0};  // bumped by every clock-jump reset

  // LCM thread only.
  std::deque<std::pair<int64_t, std::vector<Eigen::Vector3f>>> pending_scans;
  std::deque<aglcm::image_t> pending_images;  // encoded, waiting for odometry
  std::optional<int64_t> last_ugv_image_t;
  std::vector<StampedPose> jump_candidates;  // odometry far from the newest, unconfirmed

  // UGV keyframe images (still encoded) for the frontend thread.
  struct FrontendItem {
    uint64_t epoch = 0;
    aglcm::image_t image;
    uint64_t scans_pushed = 0;  ///< to the map builder before this image was queued
  };
  std::mutex frontend_mutex;
  std::condition_variable frontend_cv;
  std::deque<FrontendItem> frontend_queue;

  // UAV keyframe packets, as received, for the keyframe thread.
  struct AirPacket {
    std::string channel;
    std::vector<uint8_t> bytes;
    SteadyClock::time_point arrival;
  };
  std::mutex air_mutex;
  std::condition_variable air_cv;
  std::deque<AirPacket> air_queue;
  KeyframeAssembler assembler;  // keyframe thread only

  std::mutex window_mutex;
  std::condition_variable window_cv;
  UgvWindow window;
  uint64_t window_generation = 0;

  std::mutex agents_mutex;
  std::map<std::string, std::unique_ptr<AgentState>> agents;

  mutable std::mutex stats_mutex;
  GroundServerStats stats;
  std::map<std::string, int64_t> warnings;  // rate limiting, by kind

  std::atomic<bool> stopping{false};
  std::atomic<bool> db_dirty{false};
  std::mutex persist_mutex;
  std::condition_variable persist_cv;
  std::thread frontend_thread;
  std::thread air_thread;
  std::thread persist_thread;
  bool threads_started = false;
  int64_t next_ugv_id = 0;  // frontend thread

  explicit Impl(const GroundServerOptions& o)
      : options(o),
        map(o.map),
        builder(&map, o.map_builder),
        db(o.place_db),
        odometry(std::make_shared<OdometryBuffer>(o.odometry)) {}

  void Count(int64_t GroundServerStats::*field, int64_t n = 1) {
    std::lock_guard<std::mutex> lock(stats_mutex);
    stats.*field += n;
  }
  /// Logs a warning of `kind`: the first 5, then every 100th (with the count).
  void Warn(const std::string& kind, const std::string& what) {
    int64_t n = 0;
    {
      std::lock_guard<std::mutex> lock(stats_mutex);
      n = ++warnings[kind];
    }
    if (n <= 5 || n % 100 == 0) spdlog::warn("{} ({} {} so far)", what, n, kind);
  }
  /// Counts a malformed message in `field` and logs it, rate-limited.
  void Drop(int64_t GroundServerStats::*field, const std::string& kind, const std::string& channel,
            const std::string& what) {
    Count(field);
    Warn(kind, channel + ": " + what);
  }
  void Bad(const std::string& channel, const std::string& what) {
    Drop(&GroundServerStats::bad_messages, "bad messages", channel, what);
  }
  void Mismatch(const std::string& channel, const std::string& what) {
    Drop(&GroundServerStats::frame_id_mismatches, "frame id mismatches", channel, what);
  }
  std::shared_ptr<OdometryBuffer> Odometry() const {
    std::lock_guard<std::mutex> lock(odometry_mutex);
    return odometry;
  }

  void Subscribe();
  void StartThreads();
  void StopThreads();
  AgentState* Agent(const std::string& name);
  void AgentLoop(AgentState* agent);
  void FrontendLoop();
  void AirLoop();
  void PersistLoop();
  void ProcessAirPacket(const AirPacket& packet);
  /// Stores a (joined) UAV keyframe in the place database and wakes its estimation.
  void StoreAirKeyframe(KeyframeAssembler::Joined&& joined, SteadyClock::time_point arrival);
  void DrainPending();
  void AddOdometry(const StampedPose& pose);
  void ResetUgvTime(const std::string& why);
  void OnOdometry(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnPoints(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnImage(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnAirKeyframe(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnCameraInfo(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  bool ApplyCameraInfo(const aglcm::camera_info_t& msg, const std::string& source);
  void Save();
  void Restore();
  void LogStatus();
};

// ---------------------------------------------------------------- agents

/// At debug level, one line per estimate: what it paired and what came out,
/// to see how timing shapes a live run (which UGV window met which UAV
/// keyframes) next to the offline evaluator's.
void LogEstimate(const AgentState& agent, const UgvWindow& window, const EstimateResult& r) {
  if (!spdlog::should_log(spdlog::level::debug)) return;
  const double t0 = static_cast<double>(window.front()->t_ns) * 1e-9;
  const double t1 = static_cast<double>(window.back()->t_ns) * 1e-9;
  if (!r.success) {
    spdlog::debug("{}: estimate over UGV keyframes {:.2f}-{:.2f} s ({}) failed after {:.0f} ms: {}",
                  agent.name, t0, t1, window.size(), r.timing.total_ms, r.reason);
    return;
  }
  const Pose& T = r.T_wa_wg_single;
  spdlog::debug(
      "{}: estimate over UGV keyframes {:.2f}-{:.2f} s ({}) and UAV keyframes [{}] "
      "(newest {:.2f} s): {} pairs, {} inliers, rms {:.2f} px; alone ({:.3f}, {:.3f}, {:.3f}) m "
      "yaw {:.3f} deg; UGV camera corrected by {:.3f} deg; {:.0f} ms; {}",
      agent.name, t0, t1, window.size(), fmt::join(r.air_seqs, " "),
      static_cast<double>(r.newest_air_t_ns) * 1e-9, r.pairs, r.inliers, r.rms_reprojection_px,
      T.translation().x(), T.translation().y(), T.translation().z(), YawOf(T.linear()) * 180 / M_PI,
      Eigen::AngleAxisd(r.ugv_T_wg_c_lio.linear().transpose() * r.ugv_T_wg_c_refined.linear())
              .angle() *
          180 / M_PI,
      r.timing.total_ms, r.gate.publish ? "published" : r.gate.reason);
}

AgentState* GroundServerApp::Impl::Agent(const std::string& name) {
  std::lock_guard<std::mutex> lock(agents_mutex);
  auto it = agents.find(name);
  if (it != agents.end()) return it->second.get();
  if (static_cast<int>(agents.size()) >= options.max_air_agents) return nullptr;
  auto state = std::make_unique<AgentState>();
  state->name = name;
  state->estimator = std::make_unique<AgentEstimator>(name, options.estimator, frontend->camera());
  AgentState* raw = state.get();
  agents.emplace(name, std::move(state));
  spdlog::info("new air agent '{}': relative poses on {}", name, RelativePoseChannel(name));
  if (threads_started) raw->thread = std::thread([this, raw] { AgentLoop(raw); });
  return raw;
}

void GroundServerApp::Impl::AgentLoop(AgentState* agent) {
  // When to estimate: right after a UAV keyframe is stored, once the UGV
  // window has reached that keyframe's time (or after `kWindowWait`), so the
  // newest UAV view pairs with the UGV view of the same instant and the
  // relative pose follows the keyframe by the processing time only. While
  // the UAV is silent (gone, or out of range), a new UGV window triggers the
  // estimate instead: the place database still holds what the UAV sent.
  // Never more often than estimate_period_s.
  constexpr auto kWindowWait = std::chrono::milliseconds(500);
  const auto period = std::chrono::duration_cast<SteadyClock::duration>(
      std::chrono::duration<double>(options.estimate_period_s - 1e-3));
  uint64_t seen_window = 0;
  uint64_t seen_keyframe = 0;
  std::optional<SteadyClock::time_point> last;
  auto uav_silent = [&] {
    const int64_t arrival = agent->newest_keyframe_arrival_ns.load();
    if (agent->keyframe_generation.load() == 0 || arrival == 0) return true;
    const auto since = SteadyClock::now().time_since_epoch() - std::chrono::nanoseconds(arrival);
    return since > 2 * period;
  };
  while (!stopping) {
    UgvWindow snapshot;
    {
      std::unique_lock<std::mutex> lock(window_mutex);
      window_cv.wait_for(lock, std::chrono::milliseconds(200), [&] {
        return stopping || agent->keyframe_generation.load() != seen_keyframe ||
               (window_generation != seen_window && uav_silent());
      });
      if (stopping) return;
      const uint64_t keyframe_generation = agent->keyframe_generation.load();
      const bool new_keyframe = keyframe_generation != seen_keyframe;
      if (!new_keyframe && (window_generation == seen_window || !uav_silent())) continue;
      if (last && SteadyClock::now() - *last < period) {
        // Too soon: sleep out the period (waking for a shutdown only).
        window_cv.wait_until(lock, *last + period, [&] { return stopping.load(); });
        if (stopping) return;
      }
      if (new_keyframe) {
        const int64_t air_t_ns = agent->newest_keyframe_t_ns.load();
        window_cv.wait_for(lock, kWindowWait, [&] {
          return stopping || (!window.empty() && window.back()->t_ns >= air_t_ns);
        });
        if (stopping) return;
      }
      seen_keyframe = keyframe_generation;
      seen_window = window_generation;
      snapshot = window;
    }
    if (snapshot.empty()) continue;  // just reset by a clock jump
    last = SteadyClock::now();
    // Cameras and resets arrive from other threads; apply them here, where
    // the estimator lives.
    std::vector<std::pair<std::string, std::shared_ptr<const Camera>>> cameras;
    bool reset = false;
    {
      std::lock_guard<std::mutex> lock(agent->mutex);
      reset = agent->reset_generation != agent->applied_reset;
      agent->applied_reset = agent->reset_generation;
      if (reset || agent->camera_version != agent->applied_cameras) {
        for (const auto& [id, c] : agent->cameras) cameras.emplace_back(id, c.camera);
        agent->applied_cameras = agent->camera_version;
      }
    }
    if (reset) {
      agent->estimator =
          std::make_unique<AgentEstimator>(agent->name, options.estimator, frontend->camera());
    }
    for (const auto& [id, camera] : cameras) agent->estimator->SetAirCamera(id, camera);

    const int64_t t_ns = snapshot.back()->t_ns;
    const EstimateResult r = agent->estimator->Estimate(t_ns, snapshot, source);
    LogEstimate(*agent, snapshot, r);
    const FixGate& gate = agent->estimator->gate();
    RelativePoseEstimate out;
    out.agent = agent->name;
    out.seq = agent->out_seq++;
    out.t_ns = t_ns;
    out.status = gate.fix() ? (gate.status() == FixStatus::kLost ? aglcm::relative_pose_t::LOST
                                                                 : aglcm::relative_pose_t::TRACKING)
                            : aglcm::relative_pose_t::INITIALIZING;
    out.status_reason =
        r.success ? (r.gate.publish ? "estimate published" : r.gate.reason) : r.reason;
    if (gate.fix()) out.T_wa_wg = *gate.fix();
    out.solve_time_s = r.timing.total_ms / 1000.0;
    {
      std::lock_guard<std::mutex> lock(agent->mutex);
      if (r.success && r.gate.publish) {
        agent->covariance = r.covariance;
        agent->has_covariance = r.has_covariance;
        out.num_inliers = r.inliers;
        out.num_keyframe_pairs = r.pairs;
        out.rms_reprojection_error_px = r.rms_reprojection_px;
        out.air_t_ns = r.newest_air_t_ns;
        // Latency: from the arrival of the newest UAV keyframe used to now.
        const auto arrival = agent->received.find(r.newest_air_t_ns);
        if (arrival != agent->received.end()) {
          agent->latency_s = SecondsSince(arrival->second);
          out.latency_s = agent->latency_s;
        }
      }
      if (gate.fix()) out.covariance = agent->covariance;
      agent->status = ToString(gate.status());
      agent->reason = out.status_reason;
      agent->inliers = r.inliers;
      agent->fix = gate.fix();
      ++agent->estimates;
    }
    const aglcm::relative_pose_t msg = EncodeRelativePose(out);
    lcm->publish(RelativePoseChannel(agent->name), &msg);
    Count(&GroundServerStats::relative_poses);
  }
}

// ---------------------------------------------------------------- UGV

void GroundServerApp::Impl::FrontendLoop() {
  constexpr auto kMapWait = std::chrono::seconds(1);
  while (true) {
    FrontendItem item;
    {
      std::unique_lock<std::mutex> lock(frontend_mutex);
      frontend_cv.wait(lock, [&] { return stopping || !frontend_queue.empty(); });
      if (stopping) return;
      item = std::move(frontend_queue.front());
      frontend_queue.pop_front();
    }
    cv::Mat image;
    std::string error;
    if (!DecodeImage(item.image, &image, &error)) {
      Bad(kUgvImageChannel, error);
      continue;
    }
    // The keypoints' depth comes from the map: let the map thread insert
    // every scan that came before the image first, as the offline evaluator
    // does, so that a busy CPU does not change what the keyframe sees.
    if (builder.stats().settled() < item.scans_pushed) {
      Count(&GroundServerStats::keyframes_waited_for_map);
      if (!builder.WaitUntilSettled(item.scans_pushed, kMapWait)) {
        Count(&GroundServerStats::keyframes_map_behind);
        Warn(
            "keyframes made before the map caught up",
            fmt::format("the LiDAR map thread is more than {} s behind the UGV images; giving this "
                        "keyframe depth from the map as it is",
                        std::chrono::duration<double>(kMapWait).count()));
      }
    }
    const std::shared_ptr<OdometryBuffer> odo = Odometry();
    const UgvFrontend::Result r =
        frontend->Process(next_ugv_id++, item.image.t_ns, image, *odo, map);
    if (r.status != PoseLookupStatus::kOk) {
      Count(&GroundServerStats::keyframes_dropped);
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(window_mutex);
      if (item.epoch != ugv_epoch) continue;  // made before a clock-jump reset
      window.push_back(r.keyframe);
      while (static_cast<int>(window.size()) > options.window_size) window.pop_front();
      ++window_generation;
    }
    Count(&GroundServerStats::keyframes);
    window_cv.notify_all();
  }
}

void GroundServerApp::Impl::DrainPending() {
  const OdometryBuffer& odo = *odometry;
  while (!pending_scans.empty()) {
    PosedScan scan;
    const PoseLookupStatus st =
        frontend->PoseScan(pending_scans.front().first, pending_scans.front().second, odo, &scan);
    if (st == PoseLookupStatus::kWait) break;
    pending_scans.pop_front();
    if (st != PoseLookupStatus::kOk || !builder.Push(std::move(scan))) {
      Count(&GroundServerStats::scans_dropped);
    }
  }
  while (!pending_images.empty()) {
    const PoseLookupStatus st = frontend->ImageReady(pending_images.front().t_ns, odo);
    if (st == PoseLookupStatus::kWait) break;
    aglcm::image_t image = std::move(pending_images.front());
    pending_images.pop_front();
    if (st != PoseLookupStatus::kOk) {
      Count(&GroundServerStats::keyframes_dropped);
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(frontend_mutex);
      frontend_queue.push_back({ugv_epoch, std::move(image), builder.stats().scans_pushed});
      while (static_cast<int>(frontend_queue.size()) > options.image_queue) {
        frontend_queue.pop_front();  // the frontend is behind: keep the newest
        Count(&GroundServerStats::keyframes_dropped);
      }
    }
    frontend_cv.notify_one();
  }
}

void GroundServerApp::Impl::ResetUgvTime(const std::string& why) {
  spdlog::warn(
      "{}: resetting the UGV odometry, the images and scans waiting for it, the UGV window, "
      "the LiDAR map and every air agent's fix (UAV keyframes are kept)",
      why);
  Count(&GroundServerStats::clock_jumps);
  {
    std::lock_guard<std::mutex> lock(odometry_mutex);
    ++ugv_epoch;
    odometry->Close();
    odometry = std::make_shared<OdometryBuffer>(options.odometry);
  }
  Count(&GroundServerStats::scans_dropped, static_cast<int64_t>(pending_scans.size()));
  Count(&GroundServerStats::keyframes_dropped, static_cast<int64_t>(pending_images.size()));
  pending_scans.clear();
  pending_images.clear();
  last_ugv_image_t.reset();
  {
    std::lock_guard<std::mutex> lock(frontend_mutex);
    Count(&GroundServerStats::keyframes_dropped, static_cast<int64_t>(frontend_queue.size()));
    frontend_queue.clear();
  }
  // Scans already queued for the map are in the old world: let them land,
  // then clear (a LIO restart starts a new world; a replay rebuilds the map).
  builder.WaitUntilIdle(std::chrono::seconds(2));
  map.Clear();
  {
    std::lock_guard<std::mutex> lock(window_mutex);
    window.clear();
    ++window_generation;
  }
  window_cv.notify_all();
  std::lock_guard<std::mutex> lock(agents_mutex);
  for (auto& [name, agent] : agents) {
    std::lock_guard<std::mutex> agent_lock(agent->mutex);
    ++agent->reset_generation;
  }
}

void GroundServerApp::Impl::AddOdometry(const StampedPose& pose) {
  const std::optional<int64_t> newest = odometry->newest_t_ns();
  const int64_t jump_ns = Nanoseconds(options.clock_jump_s);
  const bool far = newest && (pose.t_ns < *newest - jump_ns || pose.t_ns > *newest + jump_ns);
  if (!far) {
    if (!jump_candidates.empty()) {
      // A few messages far from the timeline, then back on it: outliers.
      Count(&GroundServerStats::odometry_rejected, static_cast<int64_t>(jump_candidates.size()));
      Warn("odometry time outliers",
           std::string(kUgvOdometryChannel) + ": ignored " +
               std::to_string(jump_candidates.size()) +
               " odometry message(s) more than clock_jump_s from the timeline (not confirmed " +
               "by clock_jump_confirmations in a row)");
      jump_candidates.clear();
    }
    const OdometryAddStatus st = odometry->Add(pose);
    if (st == OdometryAddStatus::kAdded) {
      Count(&GroundServerStats::odometry);
    } else if (st == OdometryAddStatus::kOutOfOrder || st == OdometryAddStatus::kDuplicate) {
      Drop(&GroundServerStats::odometry_rejected, "odometry rejections", kUgvOdometryChannel,
           std::string("odometry at t_ns ") + std::to_string(pose.t_ns) + " " + ToString(st));
    } else {
      Bad(kUgvOdometryChannel, std::string("odometry rejected: ") + ToString(st));
    }
    return;
  }
  // Far from the newest pose: a clock jump once confirmed by consecutive
  // messages that agree with each other (one stray timestamp must not reset
  // the map).
  if (!jump_candidates.empty() && !(pose.t_ns > jump_candidates.back().t_ns &&
                                    pose.t_ns - jump_candidates.back().t_ns < jump_ns)) {
    Count(&GroundServerStats::odometry_rejected, static_cast<int64_t>(jump_candidates.size()));
    jump_candidates.clear();
  }
  jump_candidates.push_back(pose);
  if (static_cast<int>(jump_candidates.size()) < options.clock_jump_confirmations) return;
  const double jump_s = static_cast<double>(jump_candidates.front().t_ns - *newest) * 1e-9;
  if (jump_s < 0) {
    ResetUgvTime(fmt::format(
        "UGV clock jumped back {:.3f} s (odometry t_ns {} after {}): a replay or a restarted "
        "LIO",
        -jump_s, jump_candidates.front().t_ns, *newest));
  } else {
    spdlog::warn("UGV odometry resumed after a gap of {:.3f} s (t_ns {} after {})", jump_s,
                 jump_candidates.front().t_ns, *newest);
  }
  for (const StampedPose& p : jump_candidates) {
    if (odometry->Add(p) == OdometryAddStatus::kAdded) Count(&GroundServerStats::odometry);
  }
  jump_candidates.clear();
}

void GroundServerApp::Impl::OnOdometry(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  aglcm::odometry_t msg;
  StampedPose pose;
  std::string error = "undecodable odometry_t";
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0 ||
      !DecodeOdometry(msg, &pose, &error)) {
    Bad(channel, error);
    return;
  }
  const GroundServerOptions::FrameIds& f = options.frames;
  if ((!f.odometry_world.empty() && msg.world_frame_id != f.odometry_world) ||
      (!f.odometry_body.empty() && msg.body_frame_id != f.odometry_body)) {
    Mismatch(channel, "odometry of '" + msg.body_frame_id + "' in '" + msg.world_frame_id +
                          "', expected '" + f.odometry_body + "' in '" + f.odometry_world +
                          "' (frames.odometry_body / frames.odometry_world)");
    return;
  }
  AddOdometry(pose);
  DrainPending();
}

void GroundServerApp::Impl::OnPoints(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  aglcm::point_cloud_t msg;
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;
  std::string error = "undecodable point_cloud_t";
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0 ||
      !DecodePointCloud(msg, &points, &intensity, &error)) {
    Bad(channel, error);
    return;
  }
  if (!options.frames.lidar.empty() && msg.frame_id != options.frames.lidar) {
    Mismatch(channel, "scan in frame '" + msg.frame_id + "', expected '" + options.frames.lidar +
                          "' (frames.lidar)");
    return;
  }
  Count(&GroundServerStats::scans);
  pending_scans.emplace_back(msg.t_ns, std::move(points));
  while (static_cast<int>(pending_scans.size()) > options.pending_sensor_queue) {
    pending_scans.pop_front();
    Count(&GroundServerStats::scans_dropped);
  }
  DrainPending();
}

void GroundServerApp::Impl::OnImage(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  aglcm::image_t msg;
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0) {
    Bad(channel, "undecodable image_t");
    return;
  }
  if (!options.frames.camera.empty() && msg.frame_id != options.frames.camera) {
    Mismatch(channel, "image of camera '" + msg.frame_id + "', expected '" + options.frames.camera +
                          "' (frames.camera)");
    return;
  }
  const std::string problem = ImageProblem(msg);
  if (!problem.empty()) {
    Bad(channel, "image at t_ns " + std::to_string(msg.t_ns) + ": " + problem);
    return;
  }
  Count(&GroundServerStats::images);
  // Keyframe selection before the (costly) decoding, which the frontend
  // thread does. A time going back restarts the selection.
  const int64_t period_ns = Nanoseconds(options.ugv_keyframe_period_s) - 1000000;
  if (last_ugv_image_t && msg.t_ns >= *last_ugv_image_t &&
      msg.t_ns - *last_ugv_image_t < period_ns) {
    return;
  }
  last_ugv_image_t = msg.t_ns;
  pending_images.push_back(std::move(msg));
  while (static_cast<int>(pending_images.size()) > options.pending_sensor_queue) {
    pending_images.pop_front();
    Count(&GroundServerStats::keyframes_dropped);
  }
  DrainPending();
}

// ---------------------------------------------------------------- UAV

void GroundServerApp::Impl::OnAirKeyframe(const lcm::ReceiveBuffer* rbuf,
                                          const std::string& channel) {
  Count(&GroundServerStats::air_packets);
  AirPacket packet{channel, {}, SteadyClock::now()};
  const auto* data = static_cast<const uint8_t*>(rbuf->data);
  packet.bytes.assign(data, data + rbuf->data_size);
  {
    std::lock_guard<std::mutex> lock(air_mutex);
    air_queue.push_back(std::move(packet));
    while (static_cast<int>(air_queue.size()) > options.air_keyframe_queue) {
      air_queue.pop_front();
      Drop(&GroundServerStats::air_packets_dropped, "air packets dropped", channel,
           "UAV keyframe queue full (air_keyframe_queue): dropped the oldest packet");
    }
  }
  air_cv.notify_one();
}

void GroundServerApp::Impl::AirLoop() {
  while (true) {
    std::optional<AirPacket> packet;
    {
      std::unique_lock<std::mutex> lock(air_mutex);
      // Wake at least every air_part_timeout_s to finish split keyframes
      // whose last parts were lost.
      air_cv.wait_for(lock, std::chrono::duration<double>(options.air_part_timeout_s),
                      [&] { return stopping || !air_queue.empty(); });
      if (stopping) return;
      if (!air_queue.empty()) {
        packet = std::move(air_queue.front());
        air_queue.pop_front();
      }
    }
    if (packet) ProcessAirPacket(*packet);
    // Only with no packet waiting: a backlog (a busy machine) must not make
    // the parts still queued look lost.
    bool backlog = false;
    {
      std::lock_guard<std::mutex> lock(air_mutex);
      backlog = !air_queue.empty();
    }
    if (backlog) continue;
    const SteadyClock::time_point now = SteadyClock::now();
    for (KeyframeAssembler::Joined& joined : assembler.Expire(SteadySeconds(now))) {
      StoreAirKeyframe(std::move(joined), now);
    }
  }
}

void GroundServerApp::Impl::ProcessAirPacket(const AirPacket& packet) {
  const std::string& channel = packet.channel;
  aglcm::air_keyframe_t msg;
  if (DecodeChecked(packet.bytes.data(), static_cast<int>(packet.bytes.size()), &msg) < 0) {
    Bad(channel, "undecodable air_keyframe_t");
    return;
  }
  DecodedKeyframe d = DecodeKeyframe(msg);
  if (!d.ok) {
    Bad(channel, d.error);
    return;
  }
  if (channel != AirKeyframeChannel(d.keyframe.agent)) {
    Bad(channel, "keyframe of agent '" + d.keyframe.agent + "' on another agent's channel");
    return;
  }
  if (d.keyframe.features.descriptor_type != features->type()) {
    Bad(channel, "keyframe with '" + d.keyframe.features.descriptor_type +
                     "' descriptors; this server extracts '" + features->type() +
                     "' (both sides must use the same features)");
    return;
  }
  AgentState* agent = Agent(d.keyframe.agent);
  if (agent == nullptr) {
    Drop(&GroundServerStats::air_keyframes_rejected, "air keyframes rejected", channel,
         "more than max_air_agents air agents: keyframe ignored");
    return;
  }
  {
    const LinkBytes link = LcmLinkBytes(channel, static_cast<int64_t>(packet.bytes.size()));
    std::lock_guard<std::mutex> lock(agent->mutex);
    ++agent->packets;
    agent->recent_ip_bytes.emplace_back(packet.arrival, link.ip);
  }
  if (d.num_parts > 1) Count(&GroundServerStats::air_parts);
  std::string error;
  std::vector<KeyframeAssembler::Joined> joined =
      assembler.Add(std::move(d), SteadySeconds(packet.arrival), &error);
  if (!error.empty()) Bad(channel, error);
  for (KeyframeAssembler::Joined& j : joined) StoreAirKeyframe(std::move(j), packet.arrival);
}

void GroundServerApp::Impl::StoreAirKeyframe(KeyframeAssembler::Joined&& joined,
                                             SteadyClock::time_point arrival) {
  const std::string channel = AirKeyframeChannel(joined.keyframe.agent);
  AgentState* agent = Agent(joined.keyframe.agent);
  if (agent == nullptr) return;  // refused when its first part came
  if (joined.num_parts > 1 && joined.parts_received < joined.num_parts) {
    Count(&GroundServerStats::air_parts_lost, joined.num_parts - joined.parts_received);
    std::lock_guard<std::mutex> lock(agent->mutex);
    agent->parts_lost += joined.num_parts - joined.parts_received;
  }
  if (!joined.usable) {
    // Without a global descriptor it could never be retrieved.
    Count(&GroundServerStats::air_parts_dropped, joined.parts_received);
    Warn("air keyframes without a global descriptor",
         fmt::format("{}: keyframe {} lost both parts with the global descriptor (the first and "
                     "the last) on the link: its {} other parts dropped",
                     channel, joined.keyframe.seq, joined.parts_received));
    return;
  }
  AirKeyframe keyframe = std::move(joined.keyframe);
  const int64_t raw_seq = keyframe.seq;
  bool known_camera = true;
  bool restarted = false;
  int64_t previous_seq = -1;
  {
    std::lock_guard<std::mutex> lock(agent->mutex);
    known_camera = agent->cameras.count(keyframe.camera_id) > 0;
    if (agent->last_raw_seq && raw_seq <= *agent->last_raw_seq) {
      // The UAV numbers from 0 again: air_agent restarted. Its keyframes are
      // stored after the ones already held rather than refused as duplicates.
      restarted = true;
      previous_seq = *agent->last_raw_seq;
      agent->seq_offset = agent->max_stored_seq + 1 - raw_seq;
    } else if (agent->last_raw_seq && raw_seq > *agent->last_raw_seq + 1) {
      const int64_t lost = raw_seq - *agent->last_raw_seq - 1;
      agent->seq_gaps += lost;
      Count(&GroundServerStats::air_seq_gaps, lost);
    } else if (!agent->last_raw_seq && raw_seq + agent->seq_offset <= agent->max_stored_seq) {
      // First packet after our own restart, numbered below what the restored
      // database holds: the UAV restarted while we were down.
      restarted = true;
      previous_seq = agent->max_stored_seq;
      agent->seq_offset = agent->max_stored_seq + 1 - raw_seq;
    }
    agent->last_raw_seq = raw_seq;
    keyframe.seq = raw_seq + agent->seq_offset;
  }
  if (restarted) {
    Count(&GroundServerStats::air_restarts);
    Warn("air agent restarts",
         fmt::format("{}: keyframe seq {} does not follow seq {}: air_agent restarted? its "
                     "keyframes are stored from seq {} on",
                     agent->name, raw_seq, previous_seq, keyframe.seq));
  }
  if (!known_camera) {
    Drop(&GroundServerStats::air_keyframes_unknown_camera, "keyframes of unknown cameras", channel,
         "keyframe " + std::to_string(raw_seq) + " of camera '" + keyframe.camera_id +
             "' before its camera_info: stored, used once the camera_info arrives");
  }
  const int64_t seq = keyframe.seq;
  const int64_t air_t_ns = keyframe.t_ns;
  const PlaceDb::InsertResult ins = db.Insert(std::move(keyframe));
  std::lock_guard<std::mutex> lock(agent->mutex);
  if (!ins.success) {
    ++agent->rejected;
    Drop(&GroundServerStats::air_keyframes_rejected, "air keyframes rejected", channel,
         "keyframe " + std::to_string(raw_seq) + " not stored: " + ins.reason);
    return;
  }
  ++agent->stored;
  agent->max_stored_seq = std::max(agent->max_stored_seq, seq);
  agent->received[air_t_ns] = arrival;
  while (agent->received.size() > 64) agent->received.erase(agent->received.begin());
  Count(&GroundServerStats::air_keyframes);
  db_dirty = true;
  // Wake the agent's estimation (under window_mutex, so its wait cannot miss it).
  agent->newest_keyframe_t_ns = air_t_ns;
  agent->newest_keyframe_arrival_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(arrival.time_since_epoch()).count();
  {
    std::lock_guard<std::mutex> window_lock(window_mutex);
    ++agent->keyframe_generation;
  }
  window_cv.notify_all();
}

bool GroundServerApp::Impl::ApplyCameraInfo(const aglcm::camera_info_t& msg,
                                            const std::string& source) {
  CameraInfo info;
  std::string error;
  if (!DecodeCameraInfo(msg, &info, &error)) {
    Bad(source, error);
    return false;
  }
  std::shared_ptr<const Camera> camera;
  try {
    camera = std::make_shared<Camera>(info.params);
  } catch (const std::exception& e) {
    Bad(source, std::string("camera_info: ") + e.what());
    return false;
  }
  AgentState* agent = Agent(msg.agent);
  if (agent == nullptr) {
    Bad(source, "more than max_air_agents air agents: camera_info of '" + msg.agent + "' ignored");
    return false;
  }
  Count(&GroundServerStats::camera_infos);
  std::lock_guard<std::mutex> lock(agent->mutex);
  auto it = agent->cameras.find(info.camera_id);
  if (it != agent->cameras.end() && SameCamera(it->second.message, msg)) {
    it->second.message = msg;  // the same camera again (sent periodically)
    return true;
  }
  spdlog::info("{}: camera '{}' {} {}x{} fx {:.1f}", agent->name, info.camera_id, info.params.model,
               info.params.width, info.params.height, info.params.fx);
  agent->cameras[info.camera_id] = {msg, camera};
  ++agent->camera_version;
  db_dirty = true;
  return true;
}

void GroundServerApp::Impl::OnCameraInfo(const lcm::ReceiveBuffer* rbuf,
                                         const std::string& channel) {
  aglcm::camera_info_t msg;
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0) {
    Bad(channel, "undecodable camera_info_t");
    return;
  }
  if (!IsValidAgentName(msg.agent) || channel != AirCameraInfoChannel(msg.agent)) {
    Bad(channel, "camera_info of agent '" + msg.agent + "' on another channel");
    return;
  }
  ApplyCameraInfo(msg, channel);
}

// ---------------------------------------------------------------- persistence

void GroundServerApp::Impl::Save() {
  if (options.persistence_dir.empty()) return;
  db_dirty = false;  // changes from here on are saved next time
  const PlaceDb::SaveResult r = db.Save(options.persistence_dir + "/place_db");
  if (!r.success) {
    Count(&GroundServerStats::save_failures);
    spdlog::error("saving the place database failed: {} (the previous snapshot is intact)",
                  r.reason);
    db_dirty = true;
    return;
  }
  // Per-agent state: the camera infos, so estimation resumes before the UAV
  // resends them. Written to a temporary file and renamed (atomic).
  YAML::Node state(YAML::NodeType::Map);
  {
    std::lock_guard<std::mutex> lock(agents_mutex);
    for (const auto& [name, agent] : agents) {
      std::lock_guard<std::mutex> agent_lock(agent->mutex);
      for (const auto& [id, c] : agent->cameras) {
        std::vector<uint8_t> bytes(c.message.getEncodedSize());
        c.message.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
        state["agents"][name]["camera_infos_lcm_hex"].push_back(ToHex(bytes));
      }
    }
  }
  const std::string path = options.persistence_dir + "/state.yaml";
  {
    std::ofstream out(path + ".tmp");
    out << "# ground_server state: per air agent, its cameras' last camera_info (LCM-encoded)\n"
        << state << "\n";
    if (!out) {
      Count(&GroundServerStats::save_failures);
      spdlog::error("cannot write {}", path + ".tmp");
      db_dirty = true;
      return;
    }
  }
  std::error_code ec;
  fs::rename(path + ".tmp", path, ec);
  if (ec) {
    Count(&GroundServerStats::save_failures);
    spdlog::error("cannot rename {} to {}: {}", path + ".tmp", path, ec.message());
    db_dirty = true;
    return;
  }
  Count(&GroundServerStats::saves);
  spdlog::debug("saved {} UAV keyframes to {}", r.keyframes, options.persistence_dir);
}

void GroundServerApp::Impl::Restore() {
  if (options.persistence_dir.empty()) return;
  fs::create_directories(options.persistence_dir);
  const std::string db_dir = options.persistence_dir + "/place_db";
  if (fs::exists(db_dir + "/CURRENT")) {
    db.Load(db_dir);  // throws naming the file when the snapshot is unreadable
  }
  const std::string path = options.persistence_dir + "/state.yaml";
  if (fs::exists(path)) {
    const YAML::Node state = LoadYamlFile(path);
    for (const auto& kv : state["agents"]) {
      for (const auto& hex : kv.second["camera_infos_lcm_hex"]) {
        std::vector<uint8_t> bytes;
        aglcm::camera_info_t msg;
        if (!FromHex(hex.as<std::string>(""), &bytes) ||
            DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &msg) < 0) {
          spdlog::warn("{}: unreadable camera_info for agent '{}', ignored", path,
                       kv.first.as<std::string>());
          continue;
        }
        ApplyCameraInfo(msg, path);
      }
    }
  }
  // Where each agent's numbering stands, so a UAV that restarted while we
  // were down is told apart from one that carries on.
  std::map<std::string, std::pair<int64_t, int64_t>> per_agent;  // keyframes, max seq
  for (const PlaceDb::Id id : db.Ids()) {
    const std::optional<PlaceDb::Entry> e = db.GetEntry(id);
    if (!e) continue;
    auto& [count, max_seq] = per_agent.try_emplace(e->agent, 0, -1).first->second;
    ++count;
    max_seq = std::max(max_seq, e->seq);
  }
  for (const auto& [name, counts] : per_agent) {
    AgentState* agent = Agent(name);
    if (agent == nullptr) continue;
    std::lock_guard<std::mutex> lock(agent->mutex);
    agent->max_stored_seq = counts.second;
    spdlog::info("restored {} UAV keyframes of '{}' (seq up to {}) and {} camera(s) from {}",
                 counts.first, name, counts.second, agent->cameras.size(), options.persistence_dir);
  }
  if (per_agent.empty()) spdlog::info("no UAV keyframes to restore in {}", db_dir);
  db_dirty = false;
}

void GroundServerApp::Impl::PersistLoop() {
  std::unique_lock<std::mutex> lock(persist_mutex);
  while (!stopping) {
    persist_cv.wait_for(lock, std::chrono::duration<double>(options.save_period_s),
                        [&] { return stopping.load(); });
    if (stopping) return;
    if (!db_dirty) continue;
    lock.unlock();
    Save();
    lock.lock();
  }
}

// ---------------------------------------------------------------- status

void GroundServerApp::Impl::LogStatus() {
  GroundServerStats s;
  {
    std::lock_guard<std::mutex> lock(stats_mutex);
    s = stats;
  }
  const VoxelMapBuilderStats b = builder.stats();
  spdlog::info(
      "ugv: odometry {} (rejected {}, clock jumps {}) scans {} (dropped {}) images {} keyframes "
      "{} (dropped {}, waited for the map {}, made before it caught up {}) map {} voxels; uav "
      "packets {} (dropped {}, parts {}) keyframes stored {} "
      "(rejected {}, unknown camera {}, lost on the link {}; parts lost {}, dropped {}); place "
      "db {}; bad messages {}, frame id mismatches {}",
      s.odometry, s.odometry_rejected, s.clock_jumps, s.scans,
      s.scans_dropped + static_cast<int64_t>(b.scans_dropped), s.images, s.keyframes,
      s.keyframes_dropped, s.keyframes_waited_for_map, s.keyframes_map_behind, map.num_voxels(),
      s.air_packets, s.air_packets_dropped, s.air_parts, s.air_keyframes, s.air_keyframes_rejected,
      s.air_keyframes_unknown_camera, s.air_seq_gaps, s.air_parts_lost, s.air_parts_dropped,
      db.Size(), s.bad_messages, s.frame_id_mismatches);
  std::lock_guard<std::mutex> lock(agents_mutex);
  for (auto& [name, agent] : agents) {
    std::lock_guard<std::mutex> agent_lock(agent->mutex);
    const auto now = SteadyClock::now();
    while (!agent->recent_ip_bytes.empty() &&
           std::chrono::duration<double>(now - agent->recent_ip_bytes.front().first).count() >
               kLinkWindowS) {
      agent->recent_ip_bytes.pop_front();
    }
    int64_t recent = 0;
    for (const auto& [t, n] : agent->recent_ip_bytes) recent += n;
    std::string pose = "no fix";
    if (agent->fix) {
      const Pose& T = *agent->fix;
      pose = fmt::format("T_wa_wg ({:.3f}, {:.3f}, {:.3f}) m yaw {:.2f} deg", T.translation().x(),
                         T.translation().y(), T.translation().z(),
                         ProjectedYaw(T.linear()) * 180.0 / M_PI);
      if (agent->has_covariance) {
        const Eigen::Matrix4d& C = agent->covariance;
        pose += fmt::format(", sigma {:.3f} m {:.2f} deg",
                            std::sqrt(std::max(0.0, C(0, 0) + C(1, 1) + C(2, 2))),
                            std::sqrt(std::max(0.0, C(3, 3))) * 180.0 / M_PI);
      }
    }
    const std::string latency =
        agent->latency_s >= 0 ? fmt::format("{:.2f} s", agent->latency_s) : std::string("-");
    spdlog::info(
        "{}: {}; {}; inliers {}; latency {}; link {:.3f} Mbps (IP, last {:.0f} s); packets {} "
        "received; keyframes {} stored, {} rejected, {} lost on the link; keyframe parts {} "
        "lost; {} cameras; {} estimates; {}",
        name, agent->status, pose, agent->inliers, latency, recent * 8.0 / 1e6 / kLinkWindowS,
        kLinkWindowS, agent->packets, agent->stored, agent->rejected, agent->seq_gaps,
        agent->parts_lost, agent->cameras.size(), agent->estimates, agent->reason);
  }
}

// ---------------------------------------------------------------- lifecycle

void GroundServerApp::Impl::Subscribe() {
  subscriptions.push_back(lcm->subscribe(kUgvOdometryChannel, &Impl::OnOdometry, this));
  subscriptions.back()->setQueueCapacity(options.odometry_queue_messages);
  subscriptions.push_back(lcm->subscribe(kUgvPointsChannel, &Impl::OnPoints, this));
  subscriptions.push_back(lcm->subscribe(kUgvImageChannel, &Impl::OnImage, this));
  subscriptions.push_back(
      lcm->subscribe(AirKeyframePattern(options.air_agents), &Impl::OnAirKeyframe, this));
  subscriptions.push_back(
      lcm->subscribe(AirCameraInfoPattern(options.air_agents), &Impl::OnCameraInfo, this));
  // Keyframe packets and camera infos only wait for a queue push here.
  subscriptions[3]->setQueueCapacity(std::max(30, options.air_keyframe_queue));
}

void GroundServerApp::Impl::StartThreads() {
  builder.Start();
  frontend_thread = std::thread([this] { FrontendLoop(); });
  air_thread = std::thread([this] { AirLoop(); });
  persist_thread = std::thread([this] { PersistLoop(); });
  std::lock_guard<std::mutex> lock(agents_mutex);
  threads_started = true;
  for (auto& [name, agent] : agents) {
    AgentState* raw = agent.get();
    raw->thread = std::thread([this, raw] { AgentLoop(raw); });
  }
}

void GroundServerApp::Impl::StopThreads() {
  stopping = true;
  frontend_cv.notify_all();
  air_cv.notify_all();
  window_cv.notify_all();
  { std::lock_guard<std::mutex> lock(persist_mutex); }
  persist_cv.notify_all();
  for (std::thread* t : {&frontend_thread, &air_thread, &persist_thread}) {
    if (t->joinable()) t->join();
  }
  std::lock_guard<std::mutex> lock(agents_mutex);
  for (auto& [name, agent] : agents) {
    if (agent->thread.joinable()) agent->thread.join();
  }
  odometry->Close();
  builder.Stop();
}

GroundServerApp::GroundServerApp(const GroundServerOptions& options)
    : GroundServerApp(options, nullptr) {}

GroundServerApp::GroundServerApp(const GroundServerOptions& options, lcm::LCM* lcm)
    : impl_(new Impl(options)) {
  CheckOptions(options);
  Impl& s = *impl_;
  s.calibration = ReadCalibration(options.calibration_file, true);
  if (lcm != nullptr) {
    s.lcm = lcm;
  } else {
    const LcmUrlPlan plan =
        PlanLcmUrl(options.lcm_url, options.lcm_recv_buf_bytes, options.lcm_min_recv_buf_bytes);
    spdlog::info("{}", plan.info);
    if (!plan.warning.empty()) spdlog::warn("{}", plan.warning);
    s.owned_lcm = std::make_unique<lcm::LCM>(plan.url);
    if (!s.owned_lcm->good())
      throw std::runtime_error("cannot open LCM with url '" + plan.url + "'");
    s.lcm = s.owned_lcm.get();
  }
  LogLoadedBlas();
  s.features = CreateFeatureExtractor(options.features);
  s.global = CreateGlobalDescriptorExtractor(options.global_descriptor, s.features->type());
  s.frontend = std::make_unique<UgvFrontend>(s.calibration, s.features.get(), s.global.get(),
                                             options.frontend);
  s.Restore();
  s.Subscribe();
}

GroundServerApp::~GroundServerApp() {
  Impl& s = *impl_;
  for (lcm::Subscription* sub : s.subscriptions) s.lcm->unsubscribe(sub);
  s.StopThreads();
}

void GroundServerApp::Run(const std::atomic<bool>& stop) {
  Impl& s = *impl_;
  s.StartThreads();
  spdlog::info("ground_server: listening on {}, {}, {} and air agents' {} / {}", kUgvImageChannel,
               kUgvOdometryChannel, kUgvPointsChannel, AirKeyframePattern(s.options.air_agents),
               AirCameraInfoPattern(s.options.air_agents));
  auto last_stats = SteadyClock::now();
  while (!stop) {
    s.lcm->handleTimeout(100);
    if (SecondsSince(last_stats) >= s.options.stats_period_s) {
      s.LogStatus();
      last_stats = SteadyClock::now();
    }
  }
  s.StopThreads();
  s.Save();
  s.LogStatus();
}

void GroundServerApp::LogStatus() { impl_->LogStatus(); }

int64_t GroundServerApp::PlaceDbSize() const { return impl_->db.Size(); }

GroundServerStats GroundServerApp::stats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->stats;
}

}  // namespace ag
