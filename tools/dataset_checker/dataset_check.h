#pragma once

// Validation of a whole dataset (format v1, ../shared/spec/dataset.md) beyond
// what ReadDataset indexes: every image and scan is read, image sizes are
// compared with the calibration, and timing is summarised (rates, gaps,
// frames outside the odometry). What the spec forbids throws
// ag::InputError naming file, line and problem; what is legal but suspect
// (slow odometry, frames without odometry, gaps) is reported as a warning.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/core/error.h"

namespace ag {

struct DatasetCheckOptions {
  bool quick = false;     ///< read only a sample of the images and scans of each agent
  int quick_samples = 8;  ///< with quick: files read per agent and sensor (first, last, spaced)
  /// Odometry slower than this is a warning (Hz). The spec asks >= 10 Hz;
  /// real 10 Hz sensors jitter below it (KITTI's OXTS: 9.5-10 Hz).
  double min_odometry_rate_hz = 9.0;
  /// An interval longer than this many times the median interval of a
  /// sensor is a gap (warning).
  double gap_factor = 2.5;

  template <class V>
  void VisitFields(V& v) {
    v("quick", quick);
    v("quick_samples", quick_samples);
    v("min_odometry_rate_hz", min_odometry_rate_hz);
    v("gap_factor", gap_factor);
  }
  void Check() const {
    CheckOption(quick_samples >= 2, "quick_samples", "must be >= 2 (first and last)");
    CheckOption(min_odometry_rate_hz >= 0, "min_odometry_rate_hz", "must be >= 0");
    CheckOption(gap_factor > 1, "gap_factor", "must be > 1");
  }
};

/// Timing of one stream (images, scans, odometry or ground truth).
struct StreamStats {
  size_t count = 0;
  int64_t first_t_ns = 0;
  int64_t last_t_ns = 0;
  double rate_hz = 0;       ///< (count - 1) / duration; 0 with fewer than 2 entries
  double median_gap_s = 0;  ///< median interval (s)
  double max_gap_s = 0;     ///< longest interval (s)
  size_t gaps = 0;          ///< intervals longer than gap_factor * median
  double DurationSeconds() const { return 1e-9 * static_cast<double>(last_t_ns - first_t_ns); }
};

struct AgentCheck {
  std::string name;  ///< "ground" or the air agent name
  std::string camera_model;
  int width = 0;  ///< from calibration.yaml (px); every image read matched it
  int height = 0;
  StreamStats images;
  StreamStats scans;  ///< ground only
  StreamStats odometry;
  StreamStats groundtruth;  ///< count 0: no groundtruth.tum
  size_t images_read = 0;
  size_t scans_read = 0;
  size_t scan_points_read = 0;
  size_t images_outside_odometry = 0;  ///< timed before the first or after the last pose
  size_t scans_outside_odometry = 0;
  uint64_t bytes = 0;  ///< size of the agent's folder (sum of file sizes)
};

struct DatasetCheckReport {
  std::string dir;
  std::string name;
  int format_version = 0;
  std::vector<AgentCheck> agents;  ///< ground first, then air agents by name
  bool has_groundtruth_yaml = false;
  std::vector<std::string> T_wa_wg_agents;  ///< air agents with a T_wa_wg in groundtruth.yaml
  uint64_t bytes = 0;                       ///< size of the whole dataset folder
  std::vector<std::string> warnings;
};

/// Validates the dataset at `dir`: ReadDataset, then every image (LoadImage)
/// and scan (ReadScan) or, with options.quick, a sample; image sizes against
/// calibration.yaml; timing. Throws InputError (the first problem: file,
/// line, what) when the dataset breaks the spec; returns the summary and
/// warnings otherwise. Throws OptionError for invalid options.
DatasetCheckReport CheckDataset(const std::string& dir, const DatasetCheckOptions& options = {});

/// The summary table, groundtruth presence, size on disk and warnings, as
/// printed by tools/check_dataset.
std::string FormatReport(const DatasetCheckReport& report);

}  // namespace ag
