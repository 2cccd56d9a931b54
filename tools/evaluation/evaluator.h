#pragma once

// Offline evaluation: the air agent's encoder and the ground server's
// estimator in one process, over a dataset, deterministically (single
// thread, data in time order, nothing from the future), at the keyframe
// rates of the live system. Produces the report of ../shared/spec/report.md.

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "air_agent/frontend/air_frontend.h"
#include "common/dataset/dataset.h"
#include "ground_server/estimation/agent_estimator.h"
#include "ground_server/pipeline/ugv_frontend.h"
#include "ground_server/place_db/place_db.h"
#include "ground_server/voxel_map/voxel_map.h"
#include "tools/evaluation/plots.h"
#include "tools/evaluation/report.h"

namespace ag {

struct EvaluateOptions {
  FeatureOptions features;                    ///< both agents use the same extractor
  GlobalDescriptorOptions global_descriptor;  ///< both agents use the same place descriptor
  AirFrontend::Options air;                   ///< keyframes, governor, encodings
  double ugv_keyframe_period_s = 0.5;         ///< UGV keyframes for the sliding window (s)
  int window_size = 5;                        ///< UGV keyframes in the sliding window
  double estimate_period_s = 1.0;             ///< relative-pose estimates per agent (s)
  UgvFrontend::Options ugv;                   ///< depth association
  VoxelMap::Options map;                      ///< the LiDAR map
  PlaceDb::Options place_db;                  ///< UAV keyframe database
  EstimatorOptions estimator;                 ///< matching, RANSAC, stages, gate
  double max_duration_s = 0.0;                ///< stop after this much data (0 = all)
  /// Probability that an IP packet of the air link is lost, independently
  /// (a keyframe message is lost with any of its packets; camera info is
  /// not modelled). Seeded: a run is reproducible.
  double link_loss = 0.0;
  uint64_t link_loss_seed = 1;

  template <class V>
  void VisitFields(V& v) {
    v("features", features);
    v("global_descriptor", global_descriptor);
    v("air", air);
    v("ugv_keyframe_period_s", ugv_keyframe_period_s);
    v("window_size", window_size);
    v("estimate_period_s", estimate_period_s);
    v("ugv", ugv);
    v("map", map);
    v("place_db", place_db);
    v("estimator", estimator);
    v("max_duration_s", max_duration_s);
    v("link_loss", link_loss);
    v("link_loss_seed", link_loss_seed);
  }
  void Check() const;
};

/// One estimate as the evaluation saw it (published or not).
struct EstimateLog {
  int64_t t_ns = 0;
  bool success = false;
  bool published = false;
  std::string reason;
  Pose T_wa_wg;
  std::optional<PoseError> error;
  std::optional<PoseError> drift_free_error;  ///< see AgentRecord::Fix
  /// The estimate minus that drift-free truth, (x, y, z, yaw) in m and rad,
  /// for consistency checks against `covariance`.
  std::optional<Eigen::Vector4d> drift_free_residual;
  /// How far that drift-free truth is from groundtruth.yaml's: the two
  /// odometries' drift since the start, which no estimator can remove from
  /// `error`.
  std::optional<PoseError> truth_drift;
  std::optional<double> drift_free_error_at_ugv_m;  ///< see AgentRecord::Fix
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  bool has_covariance = false;
  int inliers = 0;
  std::vector<int64_t> air_seqs;  ///< the UAV keyframes the estimate used
  double time_ms = 0;             ///< wall clock of the estimate (EstimateTiming::total_ms)
  double stage1_ms = 0;           ///< of which stage 1 (EstimateTiming::stage1_ms)
};

struct EvaluationResult {
  nlohmann::json report;
  std::map<std::string, std::vector<EstimateLog>> estimates;  ///< per agent
  std::map<std::string, AgentRecord> agents;
  int64_t t0_ns = 0;  ///< first data time, for plots
};

/// Progress: data time done and total (s).
using ProgressFn = std::function<void(double done_s, double total_s)>;

EvaluationResult Evaluate(const Dataset& dataset, const EvaluateOptions& options,
                          const ProgressFn& progress = {});

/// One row per estimate (published or not) with its covariance's standard
/// deviations and, with ground truth, its errors: for spreadsheets and plots.
void WriteEstimatesCsv(const std::string& path, const std::vector<EstimateLog>& estimates,
                       int64_t t0_ns);

/// Writes, per air agent, the UAV trajectory mapped into the ground world with
/// the fix in force at each time (TUM, T_wg_body; poses before the first fix
/// are left out), every estimate (`<agent>_estimates.csv`) and PNG plots:
/// trajectories (UAV truth, UAV mapped, UGV) seen from above, and the errors
/// of the published fixes over time.
void WriteTrajectoryOutputs(const Dataset& dataset, const EvaluationResult& result,
                            const std::string& out_prefix, bool plots);

}  // namespace ag
