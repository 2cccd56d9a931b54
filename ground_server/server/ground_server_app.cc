#include "ground_server/server/ground_server_app.h"

#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <mutex>
#include <thread>

#include "common/config/options.h"
#include "common/core/agent_name.h"
#include "common/dataset/dataset.h"
#include "common/wire/channels.h"
#include "common/wire/keyframe_codec.h"
#include "common/wire/message_codec.h"
#include "lcmtypes/checked_decode.h"

namespace ag {

namespace fs = std::filesystem;
using SteadyClock = std::chrono::steady_clock;

namespace {

double SecondsSince(SteadyClock::time_point t) {
  return std::chrono::duration<double>(SteadyClock::now() - t).count();
}

}  // namespace

void GroundServerOptions::Check() const {
  CheckOption(!calibration_file.empty(), "calibration_file",
              "is required (the UGV's calibration.yaml in the dataset format)");
  CheckOption(save_period_s > 0, "save_period_s", "must be > 0");
  CheckOption(ugv_keyframe_period_s > 0, "ugv_keyframe_period_s", "must be > 0");
  CheckOption(window_size >= 1, "window_size", "must be >= 1");
  CheckOption(estimate_period_s > 0, "estimate_period_s", "must be > 0");
  CheckOption(image_queue >= 1, "image_queue", "must be >= 1");
  CheckOption(pending_sensor_queue >= 1, "pending_sensor_queue", "must be >= 1");
  CheckOption(stats_period_s > 0, "stats_period_s", "must be > 0");
}

/// Everything the daemon knows about one air agent.
struct AgentState {
  std::string name;
  std::mutex mutex;  // guards the estimator and the fields below
  std::unique_ptr<AgentEstimator> estimator;
  std::optional<aglcm::camera_info_t> camera_info;      // as received, for persistence
  std::map<int64_t, SteadyClock::time_point> received;  // air t_ns -> arrival, for latency
  std::deque<std::pair<SteadyClock::time_point, int64_t>> recent_bytes;
  int64_t packets = 0;
  int64_t bytes = 0;
  int64_t seq = 0;  // relative_pose_t sequence
  // Last estimate, for the status line.
  std::string status = "initializing";
  std::string reason;
  int inliers = 0;
  double latency_s = 0;
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  std::thread thread;
};

struct GroundServerApp::Impl {
  GroundServerOptions options;
  AgentCalibration calibration;
  std::unique_ptr<lcm::LCM> lcm;
  std::unique_ptr<FeatureExtractor> features;
  std::unique_ptr<GlobalDescriptorExtractor> global;
  std::unique_ptr<UgvFrontend> frontend;
  OdometryBuffer odometry;
  VoxelMap map;
  VoxelMapBuilder builder;
  PlaceDb db;
  PlaceDbSource source{&db};

  // LCM thread only.
  std::deque<std::pair<int64_t, std::vector<Eigen::Vector3f>>> pending_scans;
  std::deque<std::pair<int64_t, cv::Mat>> pending_images;
  std::optional<int64_t> last_ugv_image_t;

  std::mutex frontend_mutex;
  std::condition_variable frontend_cv;
  std::deque<std::pair<int64_t, cv::Mat>> frontend_queue;

  std::mutex window_mutex;
  std::condition_variable window_cv;
  std::deque<std::shared_ptr<const UgvKeyframe>> window;
  uint64_t window_generation = 0;

  std::mutex agents_mutex;
  std::map<std::string, std::unique_ptr<AgentState>> agents;

  mutable std::mutex stats_mutex;
  GroundServerStats stats;
  std::atomic<bool> stopping{false};
  std::atomic<bool> db_dirty{false};
  std::thread frontend_thread;
  int64_t next_ugv_id = 0;

  Impl(const GroundServerOptions& o)
      : options(o),
        odometry(o.odometry),
        map(o.map),
        builder(&map, o.map_builder),
        db(o.place_db) {}

  void Count(int64_t GroundServerStats::*field, int64_t n = 1) {
    std::lock_guard<std::mutex> lock(stats_mutex);
    stats.*field += n;
  }
  void Bad(const std::string& channel, const std::string& what) {
    int64_t total;
    {
      std::lock_guard<std::mutex> lock(stats_mutex);
      total = ++stats.bad_messages;
    }
    // Rate-limit: the first few, then every 100th.
    if (total <= 5 || total % 100 == 0) {
      spdlog::warn("{}: {} ({} bad messages so far)", channel, what, total);
    }
  }

  AgentState* Agent(const std::string& name);
  void StartAgentThread(AgentState* agent);
  void AgentLoop(AgentState* agent);
  void FrontendLoop();
  void DrainPending();
  void OnOdometry(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnPoints(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnImage(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnAirKeyframe(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void OnCameraInfo(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void ApplyCameraInfo(AgentState* agent, const aglcm::camera_info_t& msg);
  void Save();
  void Restore();
  void LogStatus();
};

AgentState* GroundServerApp::Impl::Agent(const std::string& name) {
  std::lock_guard<std::mutex> lock(agents_mutex);
  auto it = agents.find(name);
  if (it != agents.end()) return it->second.get();
  auto state = std::make_unique<AgentState>();
  state->name = name;
  state->estimator = std::make_unique<AgentEstimator>(name, options.estimator, frontend->camera());
  AgentState* raw = state.get();
  agents.emplace(name, std::move(state));
  spdlog::info("new air agent '{}': relative poses on {}", name, RelativePoseChannel(name));
  StartAgentThread(raw);
  return raw;
}

void GroundServerApp::Impl::StartAgentThread(AgentState* agent) {
  agent->thread = std::thread([this, agent] { AgentLoop(agent); });
}

void GroundServerApp::Impl::AgentLoop(AgentState* agent) {
  uint64_t seen = 0;
  std::optional<SteadyClock::time_point> last;
  while (!stopping) {
    std::deque<std::shared_ptr<const UgvKeyframe>> snapshot;
    {
      std::unique_lock<std::mutex> lock(window_mutex);
      window_cv.wait_for(lock, std::chrono::milliseconds(200),
                         [&] { return stopping || window_generation != seen; });
      if (stopping) return;
      if (window_generation == seen) continue;
      if (last && SecondsSince(*last) < options.estimate_period_s - 1e-3) continue;
      seen = window_generation;
      snapshot = window;
    }
    last = SteadyClock::now();
    const int64_t t_ns = snapshot.back()->t_ns;
    RelativePoseEstimate out;
    {
      std::lock_guard<std::mutex> lock(agent->mutex);
      const EstimateResult r = agent->estimator->Estimate(t_ns, snapshot, source);
      const FixGate& gate = agent->estimator->gate();
      out.agent = agent->name;
      out.seq = agent->seq++;
      out.t_ns = t_ns;
      out.status = gate.fix()
                       ? (gate.status() == FixStatus::kLost ? aglcm::relative_pose_t::LOST
                                                            : aglcm::relative_pose_t::TRACKING)
                       : aglcm::relative_pose_t::INITIALIZING;
      out.status_reason =
          r.success ? (r.gate.publish ? "estimate published" : r.gate.reason) : r.reason;
      if (gate.fix()) out.T_wa_wg = *gate.fix();
      if (r.success && r.gate.publish) {
        out.covariance = r.covariance;
        agent->covariance = r.covariance;
        out.num_inliers = r.inliers;
        out.num_keyframe_pairs = r.pairs;
        out.rms_reprojection_error_px = r.rms_reprojection_px;
        out.air_t_ns = r.newest_air_t_ns;
      } else {
        out.covariance = agent->covariance;
      }
      out.solve_time_s = r.timing.total_ms / 1000.0;
      agent->status = ToString(gate.status());
      agent->reason = out.status_reason;
      agent->inliers = r.inliers;
      // Latency: from the arrival of the newest UAV keyframe used to now.
      const auto arrival = agent->received.find(r.newest_air_t_ns);
      if (r.success && arrival != agent->received.end()) {
        agent->latency_s = SecondsSince(arrival->second);
        out.latency_s = agent->latency_s;
      }
    }
    const aglcm::relative_pose_t msg = EncodeRelativePose(out);
    lcm->publish(RelativePoseChannel(agent->name), &msg);
    Count(&GroundServerStats::relative_poses);
  }
}

void GroundServerApp::Impl::FrontendLoop() {
  while (true) {
    std::pair<int64_t, cv::Mat> item;
    {
      std::unique_lock<std::mutex> lock(frontend_mutex);
      frontend_cv.wait(lock, [&] { return stopping || !frontend_queue.empty(); });
      if (stopping) return;
      item = std::move(frontend_queue.front());
      frontend_queue.pop_front();
    }
    const UgvFrontend::Result r =
        frontend->Process(next_ugv_id++, item.first, item.second, odometry, map);
    if (r.status != PoseLookupStatus::kOk) continue;
    Count(&GroundServerStats::keyframes);
    {
      std::lock_guard<std::mutex> lock(window_mutex);
      window.push_back(r.keyframe);
      while (static_cast<int>(window.size()) > options.window_size) window.pop_front();
      ++window_generation;
    }
    window_cv.notify_all();
  }
}

void GroundServerApp::Impl::DrainPending() {
  while (!pending_scans.empty()) {
    PosedScan scan;
    const PoseLookupStatus st = frontend->PoseScan(pending_scans.front().first,
                                                   pending_scans.front().second, odometry, &scan);
    if (st == PoseLookupStatus::kWait) break;
    pending_scans.pop_front();
    if (st == PoseLookupStatus::kOk && !builder.Push(std::move(scan))) {
      Count(&GroundServerStats::scans_dropped);
    }
  }
  const SensorMount camera_mount{calibration.camera.T_body_camera,
                                 calibration.camera.time_offset_s};
  while (!pending_images.empty()) {
    const PoseLookupStatus st =
        odometry.SensorPoseAt(pending_images.front().first, camera_mount).status;
    if (st == PoseLookupStatus::kWait) break;
    auto item = std::move(pending_images.front());
    pending_images.pop_front();
    if (st != PoseLookupStatus::kOk) continue;
    {
      std::lock_guard<std::mutex> lock(frontend_mutex);
      frontend_queue.push_back(std::move(item));
      while (static_cast<int>(frontend_queue.size()) > options.image_queue) {
        frontend_queue.pop_front();  // the frontend is behind: keep the newest
        Count(&GroundServerStats::keyframes_dropped);
      }
    }
    frontend_cv.notify_one();
  }
}

void GroundServerApp::Impl::OnOdometry(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  aglcm::odometry_t msg;
  StampedPose pose;
  std::string error = "undecodable message";
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0 ||
      !DecodeOdometry(msg, &pose, &error)) {
    Bad(channel, error);
    return;
  }
  const OdometryAddStatus st = odometry.Add(pose);
  if (st != OdometryAddStatus::kAdded) {
    Bad(channel, std::string("odometry rejected: ") + ToString(st));
    return;
  }
  Count(&GroundServerStats::odometry);
  DrainPending();
}

void GroundServerApp::Impl::OnPoints(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  aglcm::point_cloud_t msg;
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;
  std::string error = "undecodable message";
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0 ||
      !DecodePointCloud(msg, &points, &intensity, &error)) {
    Bad(channel, error);
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
    Bad(channel, "undecodable message");
    return;
  }
  Count(&GroundServerStats::images);
  // Keyframe selection before the (costly) image decoding.
  if (last_ugv_image_t && msg.t_ns - *last_ugv_image_t <
                              static_cast<int64_t>(options.ugv_keyframe_period_s * 1e9) - 1000000) {
    return;
  }
  cv::Mat image;
  std::string error;
  if (!DecodeImage(msg, &image, &error)) {
    Bad(channel, error);
    return;
  }
  last_ugv_image_t = msg.t_ns;
  pending_images.emplace_back(msg.t_ns, std::move(image));
  while (static_cast<int>(pending_images.size()) > options.pending_sensor_queue) {
    pending_images.pop_front();
    Count(&GroundServerStats::keyframes_dropped);
  }
  DrainPending();
}

void GroundServerApp::Impl::OnAirKeyframe(const lcm::ReceiveBuffer* rbuf,
                                          const std::string& channel) {
  aglcm::air_keyframe_t msg;
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0) {
    Bad(channel, "undecodable air keyframe");
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
  AgentState* agent = Agent(d.keyframe.agent);
  const int64_t seq = d.keyframe.seq;
  const int64_t air_t_ns = d.keyframe.t_ns;
  const PlaceDb::InsertResult ins = db.Insert(std::move(d.keyframe));
  {
    std::lock_guard<std::mutex> lock(agent->mutex);
    ++agent->packets;
    agent->bytes += static_cast<int64_t>(rbuf->data_size);
    agent->recent_bytes.emplace_back(SteadyClock::now(), static_cast<int64_t>(rbuf->data_size));
    agent->received[air_t_ns] = SteadyClock::now();
    while (agent->received.size() > 64) agent->received.erase(agent->received.begin());
  }
  if (!ins.success) {
    Count(&GroundServerStats::air_keyframes_rejected);
    Bad(channel, "keyframe " + std::to_string(seq) + " not stored: " + ins.reason);
    return;
  }
  Count(&GroundServerStats::air_keyframes);
  db_dirty = true;
}

void GroundServerApp::Impl::ApplyCameraInfo(AgentState* agent, const aglcm::camera_info_t& msg) {
  CameraInfo info;
  std::string error;
  if (!DecodeCameraInfo(msg, &info, &error)) {
    Bad(AirCameraInfoChannel(msg.agent), error);
    return;
  }
  std::lock_guard<std::mutex> lock(agent->mutex);
  const bool first = !agent->estimator->HasAirCamera(info.camera_id);
  agent->estimator->SetAirCamera(info.camera_id, std::make_shared<Camera>(info.params));
  agent->camera_info = msg;
  if (first) {
    spdlog::info("{}: camera '{}' {} {}x{} fx {:.1f}", agent->name, info.camera_id,
                 info.params.model, info.params.width, info.params.height, info.params.fx);
    db_dirty = true;
  }
}

void GroundServerApp::Impl::OnCameraInfo(const lcm::ReceiveBuffer* rbuf,
                                         const std::string& channel) {
  aglcm::camera_info_t msg;
  if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0) {
    Bad(channel, "undecodable camera_info");
    return;
  }
  if (!IsValidAgentName(msg.agent) || channel != AirCameraInfoChannel(msg.agent)) {
    Bad(channel, "camera_info of agent '" + msg.agent + "' on another channel");
    return;
  }
  ApplyCameraInfo(Agent(msg.agent), msg);
}

void GroundServerApp::Impl::Save() {
  if (options.persistence_dir.empty()) return;
  const PlaceDb::SaveResult r = db.Save(options.persistence_dir + "/place_db");
  if (!r.success) {
    spdlog::error("saving the place database failed: {} (the previous snapshot is intact)",
                  r.reason);
    return;
  }
  // Per-agent state: the camera info, so estimation resumes before the UAV
  // resends it. Written to a temporary file and renamed (atomic).
  YAML::Node state(YAML::NodeType::Map);
  {
    std::lock_guard<std::mutex> lock(agents_mutex);
    for (const auto& [name, agent] : agents) {
      std::lock_guard<std::mutex> agent_lock(agent->mutex);
      if (!agent->camera_info) continue;
      const aglcm::camera_info_t& c = *agent->camera_info;
      std::vector<uint8_t> bytes(c.getEncodedSize());
      c.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
      std::string hex;
      static const char* kHex = "0123456789abcdef";
      for (uint8_t b : bytes) {
        hex += kHex[b >> 4];
        hex += kHex[b & 15];
      }
      state["agents"][name]["camera_info_lcm_hex"] = hex;
    }
  }
  const std::string path = options.persistence_dir + "/state.yaml";
  {
    std::ofstream out(path + ".tmp");
    out << "# ground_server state: per air agent, the last camera_info (LCM-encoded)\n"
        << state << "\n";
    if (!out) {
      spdlog::error("cannot write {}", path);
      return;
    }
  }
  fs::rename(path + ".tmp", path);
  db_dirty = false;
  spdlog::debug("saved {} UAV keyframes to {}", r.keyframes, options.persistence_dir);
}

void GroundServerApp::Impl::Restore() {
  if (options.persistence_dir.empty()) return;
  fs::create_directories(options.persistence_dir);
  const std::string db_dir = options.persistence_dir + "/place_db";
  if (fs::exists(db_dir + "/CURRENT")) {
    db.Load(db_dir);
    spdlog::info("restored {} UAV keyframes from {}", db.Size(), db_dir);
  }
  const std::string path = options.persistence_dir + "/state.yaml";
  if (!fs::exists(path)) return;
  const YAML::Node state = LoadYamlFile(path);
  for (const auto& kv : state["agents"]) {
    const std::string hex = kv.second["camera_info_lcm_hex"].as<std::string>("");
    std::vector<uint8_t> bytes(hex.size() / 2);
    for (size_t i = 0; i < bytes.size(); ++i)
      bytes[i] = static_cast<uint8_t>(std::stoi(hex.substr(2 * i, 2), nullptr, 16));
    aglcm::camera_info_t msg;
    if (DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &msg) < 0) {
      spdlog::warn("{}: unreadable camera_info for agent '{}', ignored", path,
                   kv.first.as<std::string>());
      continue;
    }
    ApplyCameraInfo(Agent(msg.agent), msg);
  }
  db_dirty = false;
}

void GroundServerApp::Impl::LogStatus() {
  GroundServerStats s;
  {
    std::lock_guard<std::mutex> lock(stats_mutex);
    s = stats;
  }
  const VoxelMapBuilderStats b = builder.stats();
  spdlog::info(
      "ugv: odometry {} scans {} (dropped {}) keyframes {} (dropped {}) map {} voxels; "
      "uav keyframes {} (rejected {}); bad messages {}",
      s.odometry, s.scans, s.scans_dropped + static_cast<int64_t>(b.scans_dropped), s.keyframes,
      s.keyframes_dropped, map.num_voxels(), s.air_keyframes, s.air_keyframes_rejected,
      s.bad_messages);
  std::lock_guard<std::mutex> lock(agents_mutex);
  for (auto& [name, agent] : agents) {
    std::lock_guard<std::mutex> agent_lock(agent->mutex);
    const auto now = SteadyClock::now();
    while (!agent->recent_bytes.empty() &&
           std::chrono::duration<double>(now - agent->recent_bytes.front().first).count() > 10.0) {
      agent->recent_bytes.pop_front();
    }
    int64_t recent = 0;
    for (const auto& [t, n] : agent->recent_bytes) recent += n;
    const auto& fix = agent->estimator->gate().fix();
    std::string pose = "no fix";
    if (fix) {
      const Eigen::Matrix4d& C = agent->covariance;
      pose = fmt::format(
          "T_wa_wg ({:.3f}, {:.3f}, {:.3f}) m yaw {:.2f} deg, sigma {:.3f} m {:.2f} deg",
          fix->translation().x(), fix->translation().y(), fix->translation().z(),
          ProjectedYaw(fix->linear()) * 180.0 / M_PI,
          std::sqrt(std::max(0.0, C(0, 0) + C(1, 1) + C(2, 2))),
          std::sqrt(std::max(0.0, C(3, 3))) * 180.0 / M_PI);
    }
    spdlog::info(
        "{}: {}; {}; inliers {}; latency {:.2f} s; link {:.3f} Mbps (LCM payload, last 10 s); "
        "{} keyframes received; {}",
        name, agent->status, pose, agent->inliers, agent->latency_s, recent * 8.0 / 1e6 / 10.0,
        agent->packets, agent->reason);
  }
}

GroundServerApp::GroundServerApp(const GroundServerOptions& options) : impl_(new Impl(options)) {
  CheckOptions(options);
  Impl& s = *impl_;
  s.calibration = ReadCalibration(options.calibration_file, true);
  s.lcm = std::make_unique<lcm::LCM>(options.lcm_url);
  if (!s.lcm->good())
    throw std::runtime_error("cannot open LCM with url '" + options.lcm_url + "'");
  s.features = CreateFeatureExtractor(options.features);
  s.global = CreateGlobalDescriptorExtractor(options.global_descriptor, s.features->type());
  s.frontend = std::make_unique<UgvFrontend>(s.calibration, s.features.get(), s.global.get(),
                                             options.frontend);
  s.Restore();
  s.lcm->subscribe(kUgvOdometryChannel, &Impl::OnOdometry, &s);
  s.lcm->subscribe(kUgvPointsChannel, &Impl::OnPoints, &s);
  s.lcm->subscribe(kUgvImageChannel, &Impl::OnImage, &s);
  s.lcm->subscribe(kAirKeyframePattern, &Impl::OnAirKeyframe, &s);
  s.lcm->subscribe(kAirCameraInfoPattern, &Impl::OnCameraInfo, &s);
}

GroundServerApp::~GroundServerApp() {
  Impl& s = *impl_;
  s.stopping = true;
  s.frontend_cv.notify_all();
  s.window_cv.notify_all();
  if (s.frontend_thread.joinable()) s.frontend_thread.join();
  for (auto& [name, agent] : s.agents) {
    if (agent->thread.joinable()) agent->thread.join();
  }
  s.builder.Stop();
}

void GroundServerApp::Run(const std::atomic<bool>& stop) {
  Impl& s = *impl_;
  s.builder.Start();
  s.frontend_thread = std::thread([&s] { s.FrontendLoop(); });
  spdlog::info("ground_server: listening on {}, {}, {} and air agents' {} / {}", kUgvImageChannel,
               kUgvOdometryChannel, kUgvPointsChannel, kAirKeyframePattern, kAirCameraInfoPattern);
  auto last_stats = SteadyClock::now();
  auto last_save = SteadyClock::now();
  while (!stop) {
    s.lcm->handleTimeout(100);
    if (SecondsSince(last_stats) >= s.options.stats_period_s) {
      s.LogStatus();
      last_stats = SteadyClock::now();
    }
    if (s.db_dirty && SecondsSince(last_save) >= s.options.save_period_s) {
      s.Save();
      last_save = SteadyClock::now();
    }
  }
  s.stopping = true;
  s.frontend_cv.notify_all();
  s.window_cv.notify_all();
  if (s.frontend_thread.joinable()) s.frontend_thread.join();
  for (auto& [name, agent] : s.agents) {
    if (agent->thread.joinable()) agent->thread.join();
  }
  s.builder.Stop();
  s.Save();
  s.LogStatus();
}

GroundServerStats GroundServerApp::stats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->stats;
}

}  // namespace ag
