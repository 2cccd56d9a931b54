// relative_pose_monitor: subscribes to the UAV keyframe packets and the ground
// server's relative poses and shows, per air agent, the current T_wa_wg, its
// status and uncertainty, the link bandwidth the packets use and the
// end-to-end latency (keyframe packet received -> relative pose received for
// that keyframe). With --dataset, also the ground truth and the errors: against
// groundtruth.yaml, and "drift-free" against the relation of the two odometry
// worlds when the estimate was made (what an estimator can observe; the
// difference is the odometries' drift), as tools/evaluate reports them.
//
//   relative_pose_monitor --dataset /tmp/covisible --duration 90 --require-fix
//
// Exit status: 0; 1 with --require-fix when an air agent has no fix (status
// TRACKING) at the end; 2 on bad arguments, an unreadable dataset or no LCM.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/dataset/dataset.h"
#include "common/dataset/ground_truth.h"
#include "common/geometry/pose.h"
#include "common/wire/channels.h"
#include "common/wire/link_bytes.h"
#include "common/wire/message_codec.h"
#include "lcmtypes/aglcm/air_keyframe_t.hpp"
#include "lcmtypes/aglcm/relative_pose_t.hpp"
#include "lcmtypes/checked_decode.h"

namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

using Clock = std::chrono::steady_clock;
constexpr double kRadToDeg = 180.0 / M_PI;

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

struct AgentView {
  // Link: keyframe packets as received (time, IPv4 bytes on the link).
  std::vector<std::pair<Clock::time_point, int64_t>> packets;
  std::map<int64_t, Clock::time_point> packet_time_by_t;  // keyframe t_ns (air clock)
  int64_t last_air_t_ns = 0;                              // newest keyframe an estimate has used
  // Ground server output.
  int64_t poses = 0;
  int64_t fixes = 0;  // messages with status TRACKING
  std::optional<ag::RelativePoseEstimate> last;
  std::optional<ag::RelativePoseEstimate> last_fix;
  // The newest TRACKING message with a new estimate (air_t_ns set): a
  // repeat of the current fix has no drift-free error of its own.
  std::optional<ag::RelativePoseEstimate> last_estimated_fix;
  std::vector<double> latency_s;
  // Errors of the TRACKING messages (with --dataset): against groundtruth.yaml,
  // and drift-free for those that carry a new estimate (see DriftFreeTruth).
  std::vector<double> error_m, error_deg, drift_free_m, drift_free_deg;
  int64_t bad = 0;
};

/// Mean over [first, last + 1 s) and the largest sum over any 1 s window, Mbit/s.
std::pair<double, double> Bandwidth(
    const std::vector<std::pair<Clock::time_point, int64_t>>& packets) {
  if (packets.empty()) return {0, 0};
  int64_t total = 0, worst = 0;
  for (size_t i = 0; i < packets.size(); ++i) {
    total += packets[i].second;
    int64_t window = 0;
    for (size_t j = i;
         j < packets.size() && packets[j].first < packets[i].first + std::chrono::seconds(1); ++j) {
      window += packets[j].second;
    }
    worst = std::max(worst, window);
  }
  const double span =
      std::chrono::duration<double>(packets.back().first - packets.front().first).count() + 1.0;
  return {total * 8e-6 / span, worst * 8e-6};
}

class Monitor {
 public:
  Monitor(const std::optional<ag::Dataset>& dataset, std::ofstream* jsonl, bool quiet)
      : dataset_(dataset), jsonl_(jsonl), quiet_(quiet) {}

  void OnKeyframe(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    aglcm::air_keyframe_t msg;
    const std::string agent = channel.substr(std::string("AG_AIR_KEYFRAME_").size());
    AgentView& view = agents_[agent];
    if (ag::DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) <= 0) {
      ++view.bad;
      return;
    }
    const Clock::time_point now = Clock::now();
    view.packets.emplace_back(now, ag::LcmLinkBytes(channel, rbuf->data_size).ip);
    view.packet_time_by_t[msg.t_ns] = now;
    while (view.packet_time_by_t.size() > 1000) {
      view.packet_time_by_t.erase(view.packet_time_by_t.begin());
    }
  }

  void OnRelativePose(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    const Clock::time_point now = Clock::now();
    aglcm::relative_pose_t msg;
    ag::RelativePoseEstimate e;
    std::string error;
    const std::string agent = channel.substr(std::string("AG_RELATIVE_POSE_").size());
    AgentView& view = agents_[agent];
    if (ag::DecodeChecked(rbuf->data, static_cast<int>(rbuf->data_size), &msg) <= 0 ||
        !ag::DecodeRelativePose(msg, &e, &error)) {
      ++view.bad;
      spdlog::warn("{}: undecodable relative pose ({})", channel, error);
      return;
    }
    ++view.poses;
    view.last = e;
    // Latency of an estimate that used a keyframe no earlier estimate used
    // (repeats of the current fix, and estimates from old keyframes
    // retrieved from the database, say nothing about the pipeline's delay).
    std::optional<double> latency;
    if (e.status != aglcm::relative_pose_t::INITIALIZING && e.air_t_ns > view.last_air_t_ns) {
      if (const auto it = view.packet_time_by_t.find(e.air_t_ns);
          it != view.packet_time_by_t.end()) {
        latency = std::chrono::duration<double>(now - it->second).count();
      }
      view.last_air_t_ns = e.air_t_ns;
    }
    if (e.status == aglcm::relative_pose_t::TRACKING) {
      ++view.fixes;
      view.last_fix = e;
      if (e.air_t_ns != 0) view.last_estimated_fix = e;
      if (latency) view.latency_s.push_back(*latency);
    }
    std::optional<ag::PoseError> err, drift_free;
    if (e.status != aglcm::relative_pose_t::INITIALIZING) {
      if (const std::optional<ag::Pose> truth = Truth(agent)) {
        err = ag::FourDofError(e.T_wa_wg, *truth);
      }
      if (const std::optional<ag::Pose> observable = DriftFreeTruth(agent, e)) {
        drift_free = ag::FourDofError(e.T_wa_wg, *observable);
      }
    }
    if (e.status == aglcm::relative_pose_t::TRACKING) {
      if (err) {
        view.error_m.push_back(err->translation_m);
        view.error_deg.push_back(err->yaw_deg);
      }
      if (drift_free) {
        view.drift_free_m.push_back(drift_free->translation_m);
        view.drift_free_deg.push_back(drift_free->yaw_deg);
      }
    }
    if (!quiet_) {
      std::printf("%s %-12s seq %lld  x %8.3f y %8.3f z %7.3f yaw %8.3f deg  sd %.3f m %.2f deg",
                  agent.c_str(), StatusName(e.status), static_cast<long long>(e.seq),
                  e.T_wa_wg.translation().x(), e.T_wa_wg.translation().y(),
                  e.T_wa_wg.translation().z(), ag::ProjectedYaw(e.T_wa_wg.linear()) * kRadToDeg,
                  std::sqrt(std::max(0.0, e.covariance.trace() - e.covariance(3, 3))),
                  std::sqrt(std::max(0.0, e.covariance(3, 3))) * kRadToDeg);
      if (err) std::printf("  error %.3f m %.2f deg", err->translation_m, err->yaw_deg);
      if (drift_free) {
        std::printf(" (drift-free %.3f m %.2f deg)", drift_free->translation_m,
                    drift_free->yaw_deg);
      }
      if (latency) std::printf("  latency %.2f s", *latency);
      std::printf("  inliers %d%s%s\n", e.num_inliers, e.status_reason.empty() ? "" : "  ",
                  e.status_reason.c_str());
      std::fflush(stdout);
    }
    if (jsonl_) {
      *jsonl_ << "{\"agent\":\"" << agent << "\",\"seq\":" << e.seq
              << ",\"status\":" << static_cast<int>(e.status)
              << ",\"x\":" << e.T_wa_wg.translation().x()
              << ",\"y\":" << e.T_wa_wg.translation().y()
              << ",\"z\":" << e.T_wa_wg.translation().z()
              << ",\"yaw\":" << ag::ProjectedYaw(e.T_wa_wg.linear())
              << ",\"inliers\":" << e.num_inliers;
      if (latency) *jsonl_ << ",\"latency_s\":" << *latency;
      if (err) {
        *jsonl_ << ",\"error_m\":" << err->translation_m << ",\"error_deg\":" << err->yaw_deg;
      }
      if (drift_free) {
        *jsonl_ << ",\"drift_free_error_m\":" << drift_free->translation_m
                << ",\"drift_free_error_deg\":" << drift_free->yaw_deg;
      }
      *jsonl_ << "}\n";
      jsonl_->flush();
    }
  }

  /// The final table; returns the agents without a fix.
  int PrintSummary() const {
    std::map<std::string, const AgentView*> all;
    for (const auto& [name, view] : agents_) all[name] = &view;
    static const AgentView kEmpty;
    if (dataset_) {
      for (const auto& [name, data] : dataset_->air) {
        if (!all.count(name)) all[name] = &kEmpty;
      }
    }
    int without_fix = 0;
    std::printf("\n");
    for (const auto& [name, view] : all) {
      std::printf("== %s\n", name.c_str());
      const auto [mean_mbps, max_mbps] = Bandwidth(view->packets);
      std::printf(
          "  link:      %zu keyframe packets, %.3f Mbit/s mean, %.3f Mbit/s max over 1 s "
          "(IPv4 bytes)\n",
          view->packets.size(), mean_mbps, max_mbps);
      if (!view->last_fix) {
        ++without_fix;
        std::printf("  NO FIX (%lld relative-pose messages%s%s)\n",
                    static_cast<long long>(view->poses), view->last ? ", last: " : "",
                    view->last ? view->last->status_reason.c_str() : "");
        continue;
      }
      const ag::RelativePoseEstimate& f = *view->last_fix;
      const ag::Pose& T = f.T_wa_wg;
      std::printf("  estimate:  x %.3f  y %.3f  z %.3f m  yaw %.3f deg  (%lld fixes, %d inliers)\n",
                  T.translation().x(), T.translation().y(), T.translation().z(),
                  ag::ProjectedYaw(T.linear()) * kRadToDeg, static_cast<long long>(view->fixes),
                  f.num_inliers);
      if (const std::optional<ag::Pose> truth = Truth(name)) {
        const ag::PoseError e = ag::FourDofError(T, *truth);
        std::printf("  truth:     x %.3f  y %.3f  z %.3f m  yaw %.3f deg\n",
                    truth->translation().x(), truth->translation().y(), truth->translation().z(),
                    ag::ProjectedYaw(truth->linear()) * kRadToDeg);
        std::printf("  error:     %.3f m, %.3f deg (against groundtruth.yaml)\n", e.translation_m,
                    e.yaw_deg);
        const std::optional<ag::Pose> observable =
            view->last_estimated_fix ? DriftFreeTruth(name, *view->last_estimated_fix)
                                     : std::nullopt;
        if (observable) {
          const ag::PoseError d = ag::FourDofError(view->last_estimated_fix->T_wa_wg, *observable);
          const ag::PoseError drift = ag::FourDofError(*observable, *truth);
          std::printf(
              "  drift-free: %.3f m, %.3f deg (the newest fix with a new estimate, against the "
              "odometry worlds' relation then, which the odometries' drift has moved %.3f m, "
              "%.3f deg from groundtruth.yaml)\n",
              d.translation_m, d.yaw_deg, drift.translation_m, drift.yaw_deg);
        }
        std::printf("  median:    %.3f m, %.3f deg over %zu fixes", Median(view->error_m),
                    Median(view->error_deg), view->error_m.size());
        if (!view->drift_free_m.empty()) {
          std::printf("; drift-free %.3f m, %.3f deg over %zu", Median(view->drift_free_m),
                      Median(view->drift_free_deg), view->drift_free_m.size());
        }
        std::printf("\n");
      }
      std::printf(
          "  latency:   %.2f s median over %zu estimates (keyframe packet received -> the first "
          "relative pose using it received)\n",
          Median(view->latency_s), view->latency_s.size());
    }
    return without_fix;
  }

 private:
  static const char* StatusName(int8_t s) {
    switch (s) {
      case aglcm::relative_pose_t::TRACKING:
        return "TRACKING";
      case aglcm::relative_pose_t::LOST:
        return "LOST";
      default:
        return "INITIALIZING";
    }
  }
  std::optional<ag::Pose> Truth(const std::string& agent) const {
    if (!dataset_ || !dataset_->groundtruth) return std::nullopt;
    const auto it = dataset_->groundtruth->T_wa_wg.find(agent);
    if (it == dataset_->groundtruth->T_wa_wg.end()) return std::nullopt;
    return it->second;
  }
  /// The relation of the two odometry worlds when the estimate was made (the
  /// newest UAV keyframe it used, air clock; the estimate's time, ground
  /// clock): groundtruth.yaml with both odometries' drift applied. Needs
  /// groundtruth.tum of both agents, and a message with a new estimate:
  /// ground_server leaves air_t_ns 0 where it repeats the current fix.
  std::optional<ag::Pose> DriftFreeTruth(const std::string& agent,
                                         const ag::RelativePoseEstimate& e) const {
    if (e.air_t_ns == 0) return std::nullopt;
    const std::optional<ag::Pose> truth = Truth(agent);
    if (!truth) return std::nullopt;
    const auto air = dataset_->air.find(agent);
    if (air == dataset_->air.end()) return std::nullopt;
    return ag::ObservableTruth(*dataset_, air->second, e.air_t_ns, e.t_ns, *truth);
  }

  const std::optional<ag::Dataset>& dataset_;
  std::ofstream* jsonl_;
  bool quiet_;
  std::map<std::string, AgentView> agents_;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "relative_pose_monitor: shows each air agent's T_wa_wg from ground_server, the link "
      "bandwidth of its keyframe packets and the end-to-end latency; with --dataset also the "
      "ground truth and the errors"};
  std::string dataset_dir, lcm_url, jsonl_path;
  double duration_s = 0;
  bool require_fix = false, quiet = false;
  app.add_option("--dataset", dataset_dir, "dataset whose groundtruth.yaml gives the truth");
  app.add_option("--lcm-url", lcm_url, "LCM provider URL (default: LCM's / $LCM_DEFAULT_URL)");
  app.add_option("--duration", duration_s, "stop after this many seconds (0: at SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--jsonl", jsonl_path, "also write every relative pose as a JSON line here");
  app.add_flag("--require-fix", require_fix, "exit 1 when an air agent has no fix at the end");
  app.add_flag("--quiet", quiet, "only the final summary");
  CLI11_PARSE(app, argc, argv);

  std::optional<ag::Dataset> dataset;
  if (!dataset_dir.empty()) {
    try {
      dataset = ag::ReadDataset(dataset_dir);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "relative_pose_monitor: %s\n", e.what());
      return 2;
    }
  }
  std::ofstream jsonl;
  if (!jsonl_path.empty()) {
    jsonl.open(jsonl_path);
    if (!jsonl) {
      std::fprintf(stderr, "relative_pose_monitor: cannot write %s\n", jsonl_path.c_str());
      return 2;
    }
  }
  lcm::LCM lcm(lcm_url);
  if (!lcm.good()) {
    std::fprintf(stderr, "relative_pose_monitor: cannot open LCM (url '%s')\n", lcm_url.c_str());
    return 2;
  }
  Monitor monitor(dataset, jsonl_path.empty() ? nullptr : &jsonl, quiet);
  lcm::Subscription* kf = lcm.subscribe(ag::kAirKeyframePattern, &Monitor::OnKeyframe, &monitor);
  kf->setQueueCapacity(100);
  lcm.subscribe("AG_RELATIVE_POSE_[a-z0-9_]+", &Monitor::OnRelativePose, &monitor);
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  const Clock::time_point start = Clock::now();
  while (!g_stop) {
    if (duration_s > 0 &&
        std::chrono::duration<double>(Clock::now() - start).count() >= duration_s) {
      break;
    }
    lcm.handleTimeout(100);
  }
  const int without_fix = monitor.PrintSummary();
  return require_fix && without_fix > 0 ? 1 : 0;
}
