#pragma once

// The air_agent daemon: camera frames + VIO in, keyframe packets out over
// LCM. Frames come from a dataset (replayed in real time, at a speed factor,
// or as fast as possible) or from live LCM image and odometry channels.

#include <atomic>
#include <cstdint>
#include <string>

#include "air_agent/frontend/air_frontend.h"
#include "common/features/feature_extractor.h"
#include "common/features/global_descriptor.h"
#include "common/logging/logging.h"

namespace ag {

struct AirAgentOptions {
  std::string agent = "uav0";  ///< agent name ([a-z0-9_]+), channel suffix
  std::string lcm_url;         ///< LCM provider URL; empty: LCM's default / $LCM_DEFAULT_URL
  /// Live mode receives images (~200 kB bursts): kernel receive buffer asked
  /// for when lcm_url is udpm:// without a recv_buf_size (bytes; 0: leave
  /// the URL alone).
  int64_t lcm_recv_buf_bytes = 8 * 1024 * 1024;
  /// Below this granted buffer (bytes) a warning names net.core.rmem_max.
  int64_t lcm_min_recv_buf_bytes = 2 * 1024 * 1024;
  double stats_period_s = 5.0;  ///< status line period (s)
  int vio_buffer_poses = 2000;  ///< live mode: VIO poses kept for interpolation
  /// Live mode: VIO messages LCM may queue while a keyframe is processed.
  /// LCM's default (30) is 0.15 s of a 200 Hz VIO, less than one feature
  /// extraction: the poses beyond it were dropped.
  int vio_queue_messages = 1000;
  /// Live mode: the camera's calibration.yaml (dataset format); dataset mode
  /// reads the agent's own.
  std::string calibration_file;
  FeatureOptions features;
  GlobalDescriptorOptions global_descriptor;
  AirFrontend::Options frontend;
  LoggingOptions logging;

  template <class V>
  void VisitFields(V& v) {
    v("agent", agent);
    v("lcm_url", lcm_url);
    v("lcm_recv_buf_bytes", lcm_recv_buf_bytes);
    v("lcm_min_recv_buf_bytes", lcm_min_recv_buf_bytes);
    v("stats_period_s", stats_period_s);
    v("vio_buffer_poses", vio_buffer_poses);
    v("vio_queue_messages", vio_queue_messages);
    v("calibration_file", calibration_file);
    v("features", features);
    v("global_descriptor", global_descriptor);
    v("frontend", frontend);
    v("logging", logging);
  }
  void Check() const;
};

/// Counters of a run, for the status line and tests.
struct AirAgentStats {
  int64_t frames = 0;
  int64_t keyframes = 0;
  int64_t skipped = 0;              ///< keyframes the budget had no room for
  int64_t keypoints = 0;            ///< sent, summed
  int64_t bytes_lcm = 0;            ///< LCM UDP payload bytes published
  int64_t bytes_ip = 0;             ///< the same with UDP/IP headers
  int64_t bad_messages = 0;         ///< live input that failed to decode
  int64_t frames_without_pose = 0;  ///< no VIO pose at their time (dropped)
  int64_t vio_poses = 0;            ///< live mode: VIO messages received
};

class AirAgentApp {
 public:
  explicit AirAgentApp(const AirAgentOptions& options);
  ~AirAgentApp();

  /// Replays air agent `dataset_agent` of a dataset. speed > 0 plays in
  /// real time scaled by it; 0 runs as fast as possible. Returns when the data
  /// ends or `stop` becomes true.
  void RunDataset(const std::string& dataset_dir, const std::string& dataset_agent, double speed,
                  const std::atomic<bool>& stop);

  /// Consumes live image and odometry channels until `stop`.
  void RunLive(const std::atomic<bool>& stop);

  AirAgentStats stats() const { return stats_; }

 private:
  struct Impl;
  void Publish(int64_t t_camera_ns, const AirFrontend::Output& out);
  void MaybeLogStats(bool force);

  AirAgentOptions options_;
  AirAgentStats stats_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ag
