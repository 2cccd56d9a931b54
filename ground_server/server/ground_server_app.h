#pragma once

// The ground_server daemon: UGV image / odometry / point-cloud streams and
// any number of air agents' keyframe packets in, one relative pose per air
// agent out, over LCM.
//
// Threads (bounded queues between them, with drop counters):
//  - LCM: decodes messages, feeds the odometry buffer, poses scans and
//    images once the odometry covers them, stores UAV keyframes in the place
//    database;
//  - map: inserts posed scans into the voxel map (VoxelMapBuilder);
//  - frontend: UGV keyframes (features + depth association) into the window;
//  - one estimation thread per air agent, so agents never wait for each
//    other; each publishes at most once per estimate period.
// The place database and per-agent state (camera info, last fix) persist in
// a directory and are reloaded on restart.

#include <atomic>
#include <cstdint>
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
  std::string lcm_url;                 ///< LCM provider URL; empty: LCM's default
  std::string calibration_file;        ///< the UGV's calibration.yaml (dataset format); required
  std::string persistence_dir;         ///< place database + state; empty: nothing persists
  double save_period_s = 10.0;         ///< persistence snapshot period when changed (s)
  double ugv_keyframe_period_s = 0.5;  ///< UGV keyframes for the sliding window (s)
  int window_size = 5;                 ///< UGV keyframes in the window
  double estimate_period_s = 1.0;      ///< per agent, estimates and relative-pose messages (s)
  int image_queue = 4;                 ///< UGV keyframes waiting for the frontend
  int pending_sensor_queue = 200;      ///< images/scans waiting for odometry
  double stats_period_s = 5.0;         ///< status line period (s)
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
    v("calibration_file", calibration_file);
    v("persistence_dir", persistence_dir);
    v("save_period_s", save_period_s);
    v("ugv_keyframe_period_s", ugv_keyframe_period_s);
    v("window_size", window_size);
    v("estimate_period_s", estimate_period_s);
    v("image_queue", image_queue);
    v("pending_sensor_queue", pending_sensor_queue);
    v("stats_period_s", stats_period_s);
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

/// Counters, for the status line and tests.
struct GroundServerStats {
  int64_t bad_messages = 0;  ///< failed to decode or invalid
  int64_t odometry = 0;
  int64_t scans = 0;
  int64_t scans_dropped = 0;
  int64_t images = 0;
  int64_t keyframes = 0;          ///< UGV keyframes made
  int64_t keyframes_dropped = 0;  ///< frontend queue full
  int64_t air_keyframes = 0;      ///< UAV keyframes stored
  int64_t air_keyframes_rejected = 0;
  int64_t relative_poses = 0;  ///< messages published
};

class GroundServerApp {
 public:
  explicit GroundServerApp(const GroundServerOptions& options);
  ~GroundServerApp();
  GroundServerApp(const GroundServerApp&) = delete;
  GroundServerApp& operator=(const GroundServerApp&) = delete;

  /// Runs until `stop` becomes true; saves the persistence directory then.
  void Run(const std::atomic<bool>& stop);

  GroundServerStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ag
