#include "air_agent/agent/air_agent_app.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <deque>
#include <lcm/lcm-cpp.hpp>
#include <thread>

#include "common/core/agent_name.h"
#include "common/dataset/dataset.h"
#include "common/wire/channels.h"
#include "common/wire/lcm_url.h"
#include "common/wire/message_codec.h"
#include "lcmtypes/checked_decode.h"

namespace ag {

using Clock = std::chrono::steady_clock;

struct AirAgentApp::Impl {
  std::unique_ptr<lcm::LCM> lcm;
  std::unique_ptr<FeatureExtractor> features;
  std::unique_ptr<GlobalDescriptorExtractor> global;
  std::unique_ptr<AirFrontend> frontend;
  Clock::time_point last_stats = Clock::now();
  AirAgentStats stats_at_last_log;
  std::string last_gave_up;
  // Live mode.
  std::deque<StampedPose> vio;
  std::deque<std::pair<int64_t, cv::Mat>> waiting_images;  // newer than the newest VIO pose
};

void AirAgentOptions::Check() const {
  CheckOption(IsValidAgentName(agent), "agent", "'" + agent + "' is not [a-z0-9_]+");
  CheckOption(lcm_recv_buf_bytes >= 0, "lcm_recv_buf_bytes", "must be >= 0");
  CheckOption(lcm_min_recv_buf_bytes >= 0, "lcm_min_recv_buf_bytes", "must be >= 0");
  CheckOption(stats_period_s > 0, "stats_period_s", "must be > 0");
  CheckOption(vio_buffer_poses >= 2, "vio_buffer_poses", "must be >= 2");
  CheckOption(vio_queue_messages >= 1, "vio_queue_messages", "must be >= 1");
}

AirAgentApp::AirAgentApp(const AirAgentOptions& options) : options_(options), impl_(new Impl) {
  options_.Check();
  const LcmUrlPlan plan =
      PlanLcmUrl(options_.lcm_url, options_.lcm_recv_buf_bytes, options_.lcm_min_recv_buf_bytes);
  spdlog::info("{}", plan.info);
  if (!plan.warning.empty()) spdlog::warn("{}", plan.warning);
  impl_->lcm = std::make_unique<lcm::LCM>(plan.url);
  if (!impl_->lcm->good()) throw std::runtime_error("cannot open LCM with url '" + plan.url + "'");
  impl_->features = CreateFeatureExtractor(options_.features);
  impl_->global =
      CreateGlobalDescriptorExtractor(options_.global_descriptor, impl_->features->type());
}

AirAgentApp::~AirAgentApp() = default;

void AirAgentApp::Publish(int64_t t_camera_ns, const AirFrontend::Output& out) {
  if (!out.gave_up.empty() && out.gave_up != impl_->last_gave_up) {
    spdlog::info("bandwidth governor: {}", out.gave_up);
  }
  impl_->last_gave_up = out.gave_up;
  if (out.skipped) ++stats_.skipped;
  if (impl_->frontend->CameraInfoDue(t_camera_ns)) {
    const aglcm::camera_info_t info = impl_->frontend->CameraInfo(t_camera_ns);
    impl_->lcm->publish(AirCameraInfoChannel(options_.agent), &info);
    const LinkBytes b = LcmLinkBytes(AirCameraInfoChannel(options_.agent), info.getEncodedSize(),
                                     options_.frontend.mtu);
    stats_.bytes_lcm += b.lcm_udp;
    stats_.bytes_ip += b.ip;
  }
  if (!out.keyframe) return;
  for (const aglcm::air_keyframe_t& packet : out.packets) {
    impl_->lcm->publish(impl_->frontend->channel(), &packet);
  }
  ++stats_.keyframes;
  stats_.keypoints += out.keypoints;
  stats_.bytes_lcm += out.link.lcm_udp;
  stats_.bytes_ip += out.link.ip;
}

void AirAgentApp::MaybeLogStats(bool force) {
  const auto now = Clock::now();
  const double dt = std::chrono::duration<double>(now - impl_->last_stats).count();
  if (!force && dt < options_.stats_period_s) return;
  const AirAgentStats& a = impl_->stats_at_last_log;
  const int64_t kfs = stats_.keyframes - a.keyframes;
  const double mbps = dt > 0 ? (stats_.bytes_ip - a.bytes_ip) * 8.0 / 1e6 / dt : 0.0;
  std::string extra;
  if (stats_.vio_poses > 0) extra += ", vio poses " + std::to_string(stats_.vio_poses);
  if (stats_.frames_without_pose > 0) {
    extra += ", frames without pose " + std::to_string(stats_.frames_without_pose);
  }
  if (stats_.bad_messages > 0) extra += ", bad messages " + std::to_string(stats_.bad_messages);
  spdlog::info(
      "{}: frames {} keyframes {} (+{}) skipped {} keypoints/kf {} link {:.3f} Mbps "
      "(last {:.1f} s) total {:.1f} kB{}",
      options_.agent, stats_.frames, stats_.keyframes, kfs, stats_.skipped,
      kfs > 0 ? (stats_.keypoints - a.keypoints) / kfs : 0, mbps, dt, stats_.bytes_ip / 1000.0,
      extra);
  impl_->stats_at_last_log = stats_;
  impl_->last_stats = now;
}

void AirAgentApp::RunDataset(const std::string& dataset_dir, const std::string& dataset_agent,
                             double speed, const std::atomic<bool>& stop) {
  const Dataset dataset = ReadDataset(dataset_dir);
  const auto it = dataset.air.find(dataset_agent);
  if (it == dataset.air.end()) {
    std::string names;
    for (const auto& [name, _] : dataset.air) names += (names.empty() ? "" : ", ") + name;
    throw std::runtime_error("dataset " + dataset_dir + " has no air agent '" + dataset_agent +
                             "' (it has: " + names + ")");
  }
  const AgentData& agent = it->second;
  impl_->frontend =
      std::make_unique<AirFrontend>(options_.agent, options_.frontend, agent.calibration.camera,
                                    impl_->features.get(), impl_->global.get());
  spdlog::info("{}: replaying {} frames of '{}' from {} ({})", options_.agent, agent.images.size(),
               dataset_agent, dataset_dir,
               speed > 0 ? "speed x" + std::to_string(speed) : "as fast as possible");
  const auto start = Clock::now();
  const int64_t t0 = agent.images.empty() ? 0 : agent.images.front().t_ns;
  for (const SensorFrame& frame : agent.images) {
    if (stop) break;
    if (speed > 0) {
      const auto due = start + std::chrono::nanoseconds(static_cast<int64_t>(
                                   static_cast<double>(frame.t_ns - t0) / speed));
      while (!stop && Clock::now() < due) {
        std::this_thread::sleep_for(
            std::min<Clock::duration>(due - Clock::now(), std::chrono::milliseconds(50)));
      }
    }
    ++stats_.frames;
    const InterpolationResult vio =
        InterpolateInBuffer(agent.odometry, impl_->frontend->BodyTimeNs(frame.t_ns));
    if (!vio.ok()) {
      ++stats_.frames_without_pose;
      continue;
    }
    const AirFrontend::Output out = impl_->frontend->ProcessFrame(
        frame.t_ns, [&] { return LoadImage(frame, cv::IMREAD_UNCHANGED); }, vio.T);
    Publish(frame.t_ns, out);
    MaybeLogStats(false);
  }
  MaybeLogStats(true);
}

void AirAgentApp::RunLive(const std::atomic<bool>& stop) {
  if (options_.calibration_file.empty()) {
    throw OptionError("calibration_file",
                      "is required in live mode (the camera's calibration.yaml)");
  }
  const AgentCalibration calibration = ReadCalibration(options_.calibration_file, false);
  impl_->frontend =
      std::make_unique<AirFrontend>(options_.agent, options_.frontend, calibration.camera,
                                    impl_->features.get(), impl_->global.get());
  struct Handler {
    AirAgentApp* app;
    void Process(int64_t t_ns, const cv::Mat& image) {
      Impl& impl = *app->impl_;
      const std::vector<StampedPose> buffer(impl.vio.begin(), impl.vio.end());
      const InterpolationResult vio = InterpolateInBuffer(buffer, impl.frontend->BodyTimeNs(t_ns));
      // No VIO yet (kEmpty: a camera starting before the VIO, or a frame
      // arriving just before the pose of its own instant) or not yet up to
      // this frame: wait for it; OnOdometry processes the frame when it does.
      if (vio.status == InterpolationStatus::kAfterEnd ||
          vio.status == InterpolationStatus::kEmpty) {
        impl.waiting_images.emplace_back(t_ns, image);
        while (impl.waiting_images.size() > 5) {  // VIO stalled: keep only the newest frames
          impl.waiting_images.pop_front();
          ++app->stats_.frames;
          ++app->stats_.frames_without_pose;
        }
        return;
      }
      ++app->stats_.frames;
      if (!vio.ok()) {
        ++app->stats_.frames_without_pose;
        return;
      }
      app->Publish(t_ns, impl.frontend->ProcessFrame(t_ns, image, vio.T));
    }
    void OnImage(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
      aglcm::image_t msg;
      cv::Mat image;
      std::string error;
      if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0) {
        error = "undecodable message";
      } else if (DecodeImage(msg, &image, &error)) {
        Process(msg.t_ns, image);
        return;
      }
      ++app->stats_.bad_messages;
      spdlog::warn("{}: {} ({} bad messages so far)", channel, error, app->stats_.bad_messages);
    }
    void OnOdometry(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
      aglcm::odometry_t msg;
      StampedPose pose;
      std::string error = "undecodable message";
      if (DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) < 0 ||
          !DecodeOdometry(msg, &pose, &error)) {
        ++app->stats_.bad_messages;
        spdlog::warn("{}: {} ({} bad messages so far)", channel, error, app->stats_.bad_messages);
        return;
      }
      ++app->stats_.vio_poses;
      Impl& impl = *app->impl_;
      if (!impl.vio.empty() && pose.t_ns <= impl.vio.back().t_ns) return;  // out of order: drop
      impl.vio.push_back(pose);
      while (static_cast<int>(impl.vio.size()) > app->options_.vio_buffer_poses)
        impl.vio.pop_front();
      while (!impl.waiting_images.empty() &&
             impl.frontend->BodyTimeNs(impl.waiting_images.front().first) <= pose.t_ns) {
        auto [t, image] = std::move(impl.waiting_images.front());
        impl.waiting_images.pop_front();
        Process(t, image);
      }
    }
  } handler{this};
  impl_->lcm->subscribe(AirImageChannel(options_.agent), &Handler::OnImage, &handler);
  impl_->lcm->subscribe(AirOdometryChannel(options_.agent), &Handler::OnOdometry, &handler)
      ->setQueueCapacity(options_.vio_queue_messages);
  spdlog::info("{}: listening on {} and {}", options_.agent, AirImageChannel(options_.agent),
               AirOdometryChannel(options_.agent));
  while (!stop) {
    impl_->lcm->handleTimeout(100);
    MaybeLogStats(false);
  }
  MaybeLogStats(true);
}

}  // namespace ag
