#include "tools/dataset_checker/dataset_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "common/dataset/dataset.h"
#include "common/pcd/pcd_io.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

std::string Format(const char* format, double a) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, a);
  return buffer;
}

uint64_t FolderBytes(const std::string& dir) {
  uint64_t bytes = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->is_regular_file(ec)) bytes += it->file_size(ec);
  }
  return bytes;
}

StreamStats Stats(const std::vector<int64_t>& t_ns, double gap_factor) {
  StreamStats stats;
  stats.count = t_ns.size();
  if (t_ns.empty()) return stats;
  stats.first_t_ns = t_ns.front();
  stats.last_t_ns = t_ns.back();
  if (t_ns.size() < 2) return stats;
  std::vector<double> gaps;
  for (size_t i = 1; i < t_ns.size(); ++i) gaps.push_back(1e-9 * double(t_ns[i] - t_ns[i - 1]));
  stats.rate_hz = double(t_ns.size() - 1) / stats.DurationSeconds();
  stats.max_gap_s = *std::max_element(gaps.begin(), gaps.end());
  std::vector<double> sorted = gaps;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  stats.median_gap_s = sorted[sorted.size() / 2];
  stats.gaps = static_cast<size_t>(std::count_if(
      gaps.begin(), gaps.end(), [&](double g) { return g > gap_factor * stats.median_gap_s; }));
  return stats;
}

std::vector<int64_t> Times(const std::vector<SensorFrame>& frames) {
  std::vector<int64_t> t;
  t.reserve(frames.size());
  for (const SensorFrame& f : frames) t.push_back(f.t_ns);
  return t;
}

std::vector<int64_t> Times(const std::vector<StampedPose>& poses) {
  std::vector<int64_t> t;
  t.reserve(poses.size());
  for (const StampedPose& p : poses) t.push_back(p.t_ns);
  return t;
}

/// Indices of the files to read: all, or with quick first, last and evenly
/// spaced ones in between.
std::vector<size_t> Sample(size_t n, const DatasetCheckOptions& options) {
  std::vector<size_t> indices;
  const size_t k = options.quick ? std::min(n, static_cast<size_t>(options.quick_samples)) : n;
  for (size_t j = 0; j < k; ++j) {
    indices.push_back(
        k == 1 ? 0 : static_cast<size_t>(std::llround(double(j) * double(n - 1) / double(k - 1))));
  }
  return indices;
}

size_t CountOutside(const std::vector<SensorFrame>& frames, const std::vector<StampedPose>& poses) {
  if (poses.empty()) return frames.size();
  return static_cast<size_t>(std::count_if(frames.begin(), frames.end(), [&](const SensorFrame& f) {
    return f.t_ns < poses.front().t_ns || f.t_ns > poses.back().t_ns;
  }));
}

void WarnTiming(const std::string& agent, const char* stream, const StreamStats& stats,
                std::vector<std::string>* warnings) {
  if (stats.gaps == 0) return;
  warnings->push_back(agent + ": " + std::to_string(stats.gaps) + " gap(s) in the " + stream +
                      " times (longest " + Format("%.3f", stats.max_gap_s) + " s, median " +
                      Format("%.3f", stats.median_gap_s) + " s)");
}

AgentCheck CheckAgent(const AgentData& agent, bool is_ground, const DatasetCheckOptions& options,
                      std::vector<std::string>* warnings) {
  AgentCheck check;
  check.name = agent.name;
  const CameraParams& camera = agent.calibration.camera.camera;
  check.camera_model = camera.model;
  check.width = camera.width;
  check.height = camera.height;
  check.images = Stats(Times(agent.images), options.gap_factor);
  check.scans = Stats(Times(agent.scans), options.gap_factor);
  check.odometry = Stats(Times(agent.odometry), options.gap_factor);
  check.groundtruth = Stats(Times(agent.groundtruth), options.gap_factor);
  check.bytes = FolderBytes(agent.dir);

  for (size_t i : Sample(agent.images.size(), options)) {
    const cv::Mat image = LoadImage(agent.images[i]);
    if (image.cols != camera.width || image.rows != camera.height) {
      throw InputError(InputErrorKind::kBadValue, agent.images[i].path, 0,
                       "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                           " px but " + agent.dir + "/calibration.yaml says " +
                           std::to_string(camera.width) + "x" + std::to_string(camera.height));
    }
    ++check.images_read;
  }
  for (size_t i : Sample(agent.scans.size(), options)) {
    const PointCloud cloud = ReadScan(agent.scans[i].path);
    if (cloud.points.empty()) {
      warnings->push_back(agent.name + ": scan " + agent.scans[i].path + " has no point");
    }
    check.scan_points_read += cloud.points.size();
    ++check.scans_read;
  }

  check.images_outside_odometry = CountOutside(agent.images, agent.odometry);
  check.scans_outside_odometry = CountOutside(agent.scans, agent.odometry);
  if (agent.images.empty()) warnings->push_back(agent.name + ": no image");
  if (is_ground && agent.scans.empty()) warnings->push_back(agent.name + ": no scan");
  if (agent.odometry.empty()) {
    warnings->push_back(agent.name + ": odometry.tum holds no pose");
  } else if (check.odometry.count < 2 || check.odometry.rate_hz < options.min_odometry_rate_hz) {
    warnings->push_back(agent.name + ": odometry rate " + Format("%.2f", check.odometry.rate_hz) +
                        " Hz is below " + Format("%.1f", options.min_odometry_rate_hz) +
                        " Hz (the format asks >= 10 Hz)");
  }
  if (check.images_outside_odometry > 0 && !agent.odometry.empty()) {
    warnings->push_back(agent.name + ": " + std::to_string(check.images_outside_odometry) + " of " +
                        std::to_string(agent.images.size()) +
                        " images are timed outside the odometry (no pose can be interpolated)");
  }
  if (check.scans_outside_odometry > 0 && !agent.odometry.empty()) {
    warnings->push_back(agent.name + ": " + std::to_string(check.scans_outside_odometry) + " of " +
                        std::to_string(agent.scans.size()) +
                        " scans are timed outside the odometry");
  }
  WarnTiming(agent.name, "image", check.images, warnings);
  WarnTiming(agent.name, "scan", check.scans, warnings);
  WarnTiming(agent.name, "odometry", check.odometry, warnings);
  return check;
}

std::string HumanBytes(uint64_t bytes) {
  const double b = static_cast<double>(bytes);
  if (b >= 1e9) return Format("%.2f GB", b / 1e9);
  if (b >= 1e6) return Format("%.1f MB", b / 1e6);
  if (b >= 1e3) return Format("%.1f kB", b / 1e3);
  return std::to_string(bytes) + " B";
}

std::string Rate(const StreamStats& s) { return s.count >= 2 ? Format("%.2f", s.rate_hz) : "-"; }

}  // namespace

DatasetCheckReport CheckDataset(const std::string& dir, const DatasetCheckOptions& options) {
  options.Check();
  const Dataset dataset = ReadDataset(dir);
  DatasetCheckReport report;
  report.dir = dir;
  report.name = dataset.name;
  report.format_version = dataset.format_version;
  report.agents.push_back(CheckAgent(dataset.ground, true, options, &report.warnings));
  for (const auto& [name, agent] : dataset.air) {
    report.agents.push_back(CheckAgent(agent, false, options, &report.warnings));
  }
  report.has_groundtruth_yaml = dataset.groundtruth.has_value();
  if (dataset.groundtruth) {
    for (const auto& kv : dataset.groundtruth->T_wa_wg) report.T_wa_wg_agents.push_back(kv.first);
  }
  report.bytes = FolderBytes(dir);
  return report;
}

std::string FormatReport(const DatasetCheckReport& report) {
  std::string out = "dataset " + report.dir + ": '" + report.name + "', format " +
                    std::to_string(report.format_version) + ", " +
                    std::to_string(report.agents.size()) + " agent(s), " +
                    HumanBytes(report.bytes) + " on disk\n";
  char line[512];
  std::snprintf(line, sizeof(line), "%-16s %9s %7s %10s %7s %8s %7s %8s %7s %11s %8s %9s\n",
                "agent", "duration", "images", "size", "img Hz", "odometry", "odo Hz", "scans",
                "scan Hz", "groundtruth", "read", "disk");
  out += line;
  for (const AgentCheck& a : report.agents) {
    int64_t first = a.odometry.count ? a.odometry.first_t_ns : a.images.first_t_ns;
    int64_t last = a.odometry.count ? a.odometry.last_t_ns : a.images.last_t_ns;
    for (const StreamStats* s : {&a.images, &a.scans, &a.odometry}) {
      if (s->count == 0) continue;
      first = std::min(first, s->first_t_ns);
      last = std::max(last, s->last_t_ns);
    }
    const std::string size = std::to_string(a.width) + "x" + std::to_string(a.height);
    const std::string read = std::to_string(a.images_read) +
                             (a.name == "ground" ? "+" + std::to_string(a.scans_read) : "");
    std::snprintf(line, sizeof(line), "%-16s %8.2fs %7zu %10s %7s %8zu %7s %8s %7s %11s %8s %9s\n",
                  a.name.c_str(), 1e-9 * double(last - first), a.images.count, size.c_str(),
                  Rate(a.images).c_str(), a.odometry.count, Rate(a.odometry).c_str(),
                  a.name == "ground" ? std::to_string(a.scans.count).c_str() : "-",
                  a.name == "ground" ? Rate(a.scans).c_str() : "-",
                  a.groundtruth.count ? "tum" : "none", read.c_str(), HumanBytes(a.bytes).c_str());
    out += line;
  }
  out += "groundtruth.yaml: ";
  if (!report.has_groundtruth_yaml) {
    out += "absent\n";
  } else {
    std::string agents;
    for (const std::string& n : report.T_wa_wg_agents) agents += (agents.empty() ? "" : ", ") + n;
    out += "present, T_wa_wg for " + (agents.empty() ? std::string("no agent") : agents) + "\n";
  }
  const AgentCheck& ground = report.agents.front();
  if (ground.scans_read > 0) {
    out += "scans: " + std::to_string(ground.scan_points_read / ground.scans_read) +
           " points per scan on average (of those read)\n";
  }
  if (report.warnings.empty()) {
    out += "no warnings\n";
  } else {
    out += std::to_string(report.warnings.size()) + " warning(s):\n";
    for (const std::string& w : report.warnings) out += "  - " + w + "\n";
  }
  return out;
}

}  // namespace ag
