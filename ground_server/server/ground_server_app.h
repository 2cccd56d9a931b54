#pragma once

// The ground_server daemon: UGV image / odometry / point-cloud streams and
// any number of air agents' keyframe packets in, one relative pose per air
// agent out, over LCM.
//
// Threads (bounded queues between them, with drop counters):
//  - LCM: decodes the small messages (odometry, camera info), checks frame
//    ids and times, feeds the odometry buffer, poses scans once the odometry
//    covers them; images and UAV keyframes are only queued here, so a burst
//    of them never stalls the 100 Hz odometry;
//  - map: inserts posed scans into the voxel map (VoxelMapBuilder);
//  - frontend: decodes UGV keyframe images (PNG) and makes UGV keyframes
//    (features + depth association) for the window;
//  - air keyframes: decodes and validates UAV keyframe packets and stores
//    them in the place database;
//  - one estimation thread per air agent, so agents never wait for each
//    other; each publishes at most once per estimate period;
//  - persistence: snapshots the place database and per-agent state (camera
//    infos) to a directory, reloaded on restart.
// Nothing a sender puts in a message can crash the daemon: malformed or
// unexpected messages are counted (GroundServerStats) and logged, rate-limited.
//
// A UGV clock that jumps back (a replay into a running server, a restarted
// LIO) resets the time-dependent state: odometry, sensor data waiting for
// it, the UGV window, the LiDAR map and the estimators' fixes. UAV keyframes
// stay in the place database.

#include <atomic>
#include <cstdint>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>

#include "common/features/feature_extractor.h"
#include "common/features/global_descriptor.h"
#include "common/logging/logging.h"
#include "ground_server/estimation/agent_estimator.h"
#include "ground_server/odometry/odometry_buffer.h"
#include "ground_server/pipeline/ugv_frontend.h"
#include "ground_server/place_db/place_db.h"
#include "ground_server/voxel_map/voxel_map.h"
#include "ground_server/voxel_map/voxel_map_builder.h"

namespace ag {

struct GroundServerOptions {
  /// Frame ids the UGV streams must carry (empty: any); a message naming
  /// another frame is counted and dropped, so a second camera or a
  /// differently configured LIO cannot feed the wrong calibration.
  struct FrameIds {
    std::string camera = "cam0";         ///< image_t.frame_id of the UGV camera
    std::string lidar = "lidar";         ///< point_cloud_t.frame_id
    std::string odometry_world = "wg";   ///< odometry_t.world_frame_id
    std::string odometry_body = "body";  ///< odometry_t.body_frame_id

    template <class V>
    void VisitFields(V& v) {
      v("camera", camera);
      v("lidar", lidar);
      v("odometry_world", odometry_world);
      v("odometry_body", odometry_body);
    }
  };

  std::string lcm_url;  ///< LCM provider URL; empty: $LCM_DEFAULT_URL or LCM's default
  /// Kernel receive buffer asked for when lcm_url is udpm:// without a
  /// recv_buf_size of its own (bytes; 0: leave the URL alone). A scan is
  /// ~420 kB in one burst; Linux's default buffer (208 kB) loses most.
  int64_t lcm_recv_buf_bytes = 8 * 1024 * 1024;
  /// Below this granted buffer (bytes) a warning names net.core.rmem_max.
  int64_t lcm_min_recv_buf_bytes = 2 * 1024 * 1024;
  std::string calibration_file;        ///< the UGV's calibration.yaml (dataset format); required
  std::string persistence_dir;         ///< place database + state; empty: nothing persists
  double save_period_s = 10.0;         ///< persistence snapshot period when changed (s)
  double ugv_keyframe_period_s = 0.5;  ///< UGV keyframes for the sliding window (s)
  int window_size = 5;                 ///< UGV keyframes in the window
  double estimate_period_s = 1.0;      ///< per agent, at most one estimate per period (s)
  int image_queue = 4;                 ///< UGV keyframe images waiting for the frontend
  int pending_sensor_queue = 200;      ///< images/scans waiting for odometry
  /// UAV keyframe packets waiting to be decoded and stored (each part of a
  /// split keyframe is one)
  int air_keyframe_queue = 256;
  /// A split keyframe still missing parts this long after its latest part
  /// is joined from the parts that arrived (s).
  double air_part_timeout_s = 0.5;
  /// LCM's queue for the odometry channel (messages); LCM's default (30) is
  /// 0.3 s of 100 Hz odometry, less than a burst of scans and images takes.
  int odometry_queue_messages = 1000;
  int max_air_agents = 32;  ///< air agents tracked at once; keyframes of more are refused
  /// Air agents served: a POSIX extended regular expression over the whole
  /// agent name (the channel suffix), e.g. "uav[0-9]+" or "uav1|uav3".
  /// Others' channels are not even subscribed to.
  std::string air_agents = "[a-z0-9_]+";
  /// Odometry older than the newest by more than this (s), for
  /// clock_jump_confirmations messages in a row: the UGV clock went back
  /// (replay, restart), and the time-dependent state is reset.
  double clock_jump_s = 1.0;
  int clock_jump_confirmations = 5;
  double stats_period_s = 5.0;  ///< status line period (s)
  FrameIds frames;
  FeatureOptions features;
  GlobalDescriptorOptions global_descriptor;
  UgvFrontend::Options frontend;
  OdometryBuffer::Options odometry;
  VoxelMap::Options map;
  VoxelMapBuilder::Options map_builder;
  PlaceDb::Options place_db;
  EstimatorOptions estimator;
  LoggingOptions logging;

  template <class V>
  void VisitFields(V& v) {
    v("lcm_url", lcm_url);
    v("lcm_recv_buf_bytes", lcm_recv_buf_bytes);
    v("lcm_min_recv_buf_bytes", lcm_min_recv_buf_bytes);
    v("calibration_file", calibration_file);
    v("persistence_dir", persistence_dir);
    v("save_period_s", save_period_s);
    v("ugv_keyframe_period_s", ugv_keyframe_period_s);
    v("window_size", window_size);
    v("estimate_period_s", estimate_period_s);
    v("image_queue", image_queue);
    v("pending_sensor_queue", pending_sensor_queue);
    v("air_keyframe_queue", air_keyframe_queue);
    v("air_part_timeout_s", air_part_timeout_s);
    v("odometry_queue_messages", odometry_queue_messages);
    v("max_air_agents", max_air_agents);
    v("air_agents", air_agents);
    v("clock_jump_s", clock_jump_s);
    v("clock_jump_confirmations", clock_jump_confirmations);
    v("stats_period_s", stats_period_s);
    v("frames", frames);
    v("features", features);
    v("global_descriptor", global_descriptor);
    v("frontend", frontend);
    v("odometry", odometry);
    v("map", map);
    v("map_builder", map_builder);
    v("place_db", place_db);
    v("estimator", estimator);
    v("logging", logging);
  }
  void Check() const;
};

/// Counters, for the status line and tests. Every message the daemon drops
/// lands in exactly one of the *_dropped / bad / mismatch / rejected counters.
struct GroundServerStats {
  int64_t bad_messages = 0;         ///< undecodable or invalid (sizes, NaN, encoding, names)
  int64_t frame_id_mismatches = 0;  ///< UGV messages naming another frame (dropped)
  int64_t odometry = 0;             ///< odometry poses buffered
  int64_t odometry_rejected = 0;    ///< out of order or duplicate (not a confirmed clock jump)
  int64_t clock_jumps = 0;          ///< UGV clock went back: state reset
  int64_t scans = 0;                ///< scans received (valid)
  int64_t scans_dropped = 0;        ///< waiting queue full, or older than the odometry
  int64_t images = 0;     ///< UGV images received (header checks passed; decoding may still fail)
  int64_t keyframes = 0;  ///< UGV keyframes made
  int64_t keyframes_dropped = 0;  ///< waiting or frontend queue full, or no odometry for them
  /// Keyframes whose depth had to wait for the map thread to insert the
  /// scans before them, and those made without them after a 1 s wait.
  int64_t keyframes_waited_for_map = 0;
  int64_t keyframes_map_behind = 0;
  int64_t air_packets = 0;                   ///< UAV keyframe packets received (before decoding)
  int64_t air_packets_dropped = 0;           ///< decode queue full (oldest dropped)
  int64_t air_keyframes = 0;                 ///< UAV keyframes stored
  int64_t air_keyframes_rejected = 0;        ///< refused by the place database
  int64_t air_keyframes_unknown_camera = 0;  ///< stored before their camera_info arrived
  int64_t air_seq_gaps = 0;    ///< keyframes lost on the link (seq gaps, or no global descriptor)
  int64_t air_parts = 0;       ///< packets that were parts of split keyframes
  int64_t air_parts_lost = 0;  ///< parts of split keyframes that never arrived
  int64_t air_parts_dropped = 0;  ///< received, but their keyframe lost its global descriptor
  int64_t air_restarts = 0;       ///< an air agent's seq went back (restart)
  int64_t camera_infos = 0;       ///< valid camera_info messages
  int64_t relative_poses = 0;     ///< messages published
  int64_t saves = 0;              ///< persistence snapshots written
  int64_t save_failures = 0;
};

class GroundServerApp {
 public:
  explicit GroundServerApp(const GroundServerOptions& options);
  /// Uses `lcm` (not owned; must outlive the app) instead of opening
  /// options.lcm_url: tests publish to a running server on one memq://
  /// instance.
  GroundServerApp(const GroundServerOptions& options, lcm::LCM* lcm);
  ~GroundServerApp();
  GroundServerApp(const GroundServerApp&) = delete;
  GroundServerApp& operator=(const GroundServerApp&) = delete;

  /// Runs until `stop` becomes true; saves the persistence directory then.
  void Run(const std::atomic<bool>& stop);

  /// Logs the status lines now (Run does every stats_period_s).
  void LogStatus();

  /// UAV keyframes in the place database (restored ones included).
  int64_t PlaceDbSize() const;

  GroundServerStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ag
