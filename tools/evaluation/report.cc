#include "tools/evaluation/report.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numeric>

namespace ag {

SampleStats ComputeStats(std::vector<double> values) {
  SampleStats s;
  s.count = values.size();
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  const size_t n = values.size();
  s.median = n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  s.mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(n);
  // Nearest-rank percentile.
  const size_t rank = static_cast<size_t>(std::ceil(0.95 * static_cast<double>(n)));
  s.p95 = values[std::min(n - 1, rank == 0 ? 0 : rank - 1)];
  s.max = values.back();
  return s;
}

Bandwidth ComputeBandwidth(const std::vector<std::pair<int64_t, int64_t>>& packets) {
  Bandwidth b;
  if (packets.empty()) return b;
  constexpr int64_t kSecond = 1000000000LL;
  int64_t total = 0;
  for (const auto& p : packets) total += p.second;
  const double span_s =
      1e-9 * static_cast<double>(packets.back().first - packets.front().first + kSecond);
  b.mean_mbps = total * 8.0 / 1e6 / span_s;
  // Windows starting at each packet hold the worst case.
  size_t j = 0;
  int64_t sum = 0;
  int64_t worst = 0;
  for (size_t i = 0; i < packets.size(); ++i) {
    if (i > 0) sum -= packets[i - 1].second;
    if (j < i) {
      j = i;
      sum = 0;
    }
    while (j < packets.size() && packets[j].first < packets[i].first + kSecond) {
      sum += packets[j].second;
      ++j;
    }
    worst = std::max(worst, sum);
  }
  b.max_1s_mbps = worst * 8.0 / 1e6;
  return b;
}

namespace {

nlohmann::json StatsJson(const SampleStats& s, bool with_mean_max) {
  nlohmann::json j = {{"median", s.median}, {"p95", s.p95}};
  if (with_mean_max) {
    j["mean"] = s.mean;
    j["max"] = s.max;
  }
  return j;
}

}  // namespace

nlohmann::json YamlToJson(const YAML::Node& n) {
  if (n.IsMap()) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& kv : n) j[kv.first.as<std::string>()] = YamlToJson(kv.second);
    return j;
  }
  if (n.IsSequence()) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& v : n) j.push_back(YamlToJson(v));
    return j;
  }
  if (!n.IsScalar()) return nullptr;
  const std::string& text = n.Scalar();
  if (text == "true") return true;
  if (text == "false") return false;
  char* end = nullptr;
  const long long i = std::strtoll(text.c_str(), &end, 10);
  if (!text.empty() && *end == '\0') return static_cast<int64_t>(i);
  const double d = std::strtod(text.c_str(), &end);
  if (!text.empty() && *end == '\0') return d;
  return text;
}

nlohmann::json MakeReport(const ReportInput& in) {
  nlohmann::json report;
  report["format_version"] = 1;
  report["dataset"] = in.dataset;
  report["config"] = in.config;
  bool success = !in.agents.empty();
  // The same test on the drift-free error, and on an estimate exactly equal
  // to the odometry worlds' relation: a run that fails `success` but passes
  // success_drift_free failed because the odometries drifted from
  // groundtruth.yaml, not because of the estimator.
  bool success_drift_free = success;
  bool success_attainable = success;
  const auto within = [&in](const PoseError& e) {
    return e.translation_m <= in.success_translation_m && e.yaw_deg <= in.success_yaw_deg;
  };
  nlohmann::json agents = nlohmann::json::object();
  for (const auto& [name, rec] : in.agents) {
    nlohmann::json a;
    a["packets_sent"] = rec.packets_sent;
    a["bytes_sent"] = rec.bytes_sent;
    a["bytes_sent_ip"] = rec.bytes_ip;
    const Bandwidth bw = ComputeBandwidth(rec.packets);
    a["bandwidth_mbps"] = {{"mean", bw.mean_mbps}, {"max_1s", bw.max_1s_mbps}};
    a["fixes"] = rec.fixes.size();
    // Beyond the spec: what crossed the (simulated) link.
    a["link"] = {{"ip_packets", rec.ip_packets},
                 {"ip_packets_lost", rec.ip_packets_lost},
                 {"keyframes_stored", rec.keyframes_stored},
                 {"keypoints_stored", rec.keypoints_stored}};
    if (!rec.fixes.empty() && rec.first_packet_t_ns) {
      a["time_to_first_fix_s"] =
          1e-9 * static_cast<double>(rec.fixes.front().t_ns - *rec.first_packet_t_ns);
    } else {
      a["time_to_first_fix_s"] = nullptr;
    }
    std::vector<double> t_err, yaw_err, t_err_df, yaw_err_df, at_ugv_df;
    int false_fixes = 0;
    for (const auto& f : rec.fixes) {
      if (f.drift_free_error) {
        t_err_df.push_back(f.drift_free_error->translation_m);
        yaw_err_df.push_back(f.drift_free_error->yaw_deg);
      }
      if (f.drift_free_error_at_ugv_m) at_ugv_df.push_back(*f.drift_free_error_at_ugv_m);
      if (!f.error) continue;
      t_err.push_back(f.error->translation_m);
      yaw_err.push_back(f.error->yaw_deg);
      if (f.error->translation_m > in.false_fix_translation_m ||
          f.error->yaw_deg > in.false_fix_yaw_deg) {
        ++false_fixes;
      }
    }
    const bool have_errors = in.has_groundtruth && !t_err.empty();
    if (have_errors) {
      const PoseError& last = *rec.fixes.back().error;
      a["final"] = {{"translation_error_m", last.translation_m}, {"yaw_error_deg", last.yaw_deg}};
      a["translation_error_m"] = StatsJson(ComputeStats(t_err), true);
      a["yaw_error_deg"] = StatsJson(ComputeStats(yaw_err), true);
      a["false_fixes"] = false_fixes;
      if (!t_err_df.empty()) {
        a["drift_free"] = {{"translation_error_m", StatsJson(ComputeStats(t_err_df), true)},
                           {"yaw_error_deg", StatsJson(ComputeStats(yaw_err_df), true)}};
        if (!at_ugv_df.empty()) {
          a["drift_free"]["translation_error_at_ugv_m"] = StatsJson(ComputeStats(at_ugv_df), true);
        }
      }
      const AgentRecord::Fix& final_fix = rec.fixes.back();
      if (final_fix.drift_free_error && final_fix.truth_drift) {
        a["drift_free"]["final"] = {
            {"translation_error_m", final_fix.drift_free_error->translation_m},
            {"yaw_error_deg", final_fix.drift_free_error->yaw_deg}};
        a["truth_drift_final"] = {{"translation_m", final_fix.truth_drift->translation_m},
                                  {"yaw_deg", final_fix.truth_drift->yaw_deg}};
        success_drift_free = success_drift_free && within(*final_fix.drift_free_error);
        success_attainable = success_attainable && within(*final_fix.truth_drift);
      }
      success = success && within(last);
    } else {
      a["final"] = {{"translation_error_m", nullptr}, {"yaw_error_deg", nullptr}};
      a["translation_error_m"] = nullptr;
      a["yaw_error_deg"] = nullptr;
      a["false_fixes"] = in.has_groundtruth ? nlohmann::json(0) : nlohmann::json(nullptr);
      success = false;
    }
    if (rec.ugv_camera_rotation_error_deg) {
      a["ugv_camera_rotation_error_deg"] = {{"nominal", rec.ugv_camera_rotation_error_deg->first},
                                            {"stage1", rec.ugv_camera_rotation_error_deg->second}};
    }
    if (rec.ugv_camera_translation_error_m) {
      a["ugv_camera_translation_error_m"] = {
          {"nominal", rec.ugv_camera_translation_error_m->first},
          {"stage1", rec.ugv_camera_translation_error_m->second}};
    }
    if (rec.ugv_camera_time_offset_ms) {
      a["ugv_camera_time_offset_ms"] = {{"true", rec.ugv_camera_time_offset_ms->first},
                                        {"estimated", rec.ugv_camera_time_offset_ms->second}};
    }
    if (!rec.fixes.empty()) {
      const Pose& T = rec.fixes.back().T_wa_wg;
      a["final_T_wa_wg"] = {{"x", T.translation().x()},
                            {"y", T.translation().y()},
                            {"z", T.translation().z()},
                            {"yaw_deg", ProjectedYaw(T.linear()) * 180.0 / M_PI}};
    }
    agents[name] = a;
  }
  report["agents"] = agents;
  report["timing_ms"] = {
      {"estimate", StatsJson(ComputeStats(in.timing.estimate), false)},
      {"stage1", StatsJson(ComputeStats(in.timing.stage1), false)},
      {"stage2", StatsJson(ComputeStats(in.timing.stage2), false)},
      {"retrieval", StatsJson(ComputeStats(in.timing.retrieval), false)},
      {"depth_association_per_keyframe",
       StatsJson(ComputeStats(in.timing.depth_association_per_keyframe), false)},
      {"air_features_per_frame", StatsJson(ComputeStats(in.timing.air_features_per_frame), false)},
      {"matching", StatsJson(ComputeStats(in.timing.matching), false)},
      {"ransac", StatsJson(ComputeStats(in.timing.ransac), false)},
      {"stage1_tracking", StatsJson(ComputeStats(in.timing.stage1_tracking), false)}};
  report["timing_ms"]["estimate"]["max"] = ComputeStats(in.timing.estimate).max;
  report["success"] = success && in.has_groundtruth;
  // Beyond the spec; null unless every agent has a fix with a drift-free
  // truth (needs groundtruth.tum of all agents).
  const bool drift_free_known =
      in.has_groundtruth && !in.agents.empty() &&
      std::all_of(in.agents.begin(), in.agents.end(), [](const auto& a) {
        return !a.second.fixes.empty() && a.second.fixes.back().truth_drift.has_value();
      });
  report["success_drift_free"] =
      drift_free_known ? nlohmann::json(success_drift_free) : nlohmann::json(nullptr);
  report["success_attainable"] =
      drift_free_known ? nlohmann::json(success_attainable) : nlohmann::json(nullptr);
  return report;
}

}  // namespace ag
