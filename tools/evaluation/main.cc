// tools/evaluate: offline evaluation of a dataset (report.md JSON, plots, TUM).
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "common/config/options.h"
#include "common/logging/logging.h"
#include "ground_server/matching/blas_info.h"
#include "tools/evaluation/evaluator.h"

int main(int argc, char** argv) {
  CLI::App app{
      "Offline evaluation: air encoding + ground estimation over a dataset, "
      "deterministic, at the live keyframe rates. Writes the JSON report "
      "(shared/spec/report.md), a TUM file of each UAV trajectory mapped into the "
      "ground world, and PNG plots."};
  std::string dataset_dir, config_path, out_dir = "eval_out", log_level = "info";
  int keypoints = 0;
  std::string encoding, solver;
  double budget = -1;
  bool no_stage1 = false, no_reprojection = false, no_consistency = false, no_plots = false;
  double duration = 0, link_loss = -1;
  int64_t max_part_bytes = -1;
  app.add_option("--dataset", dataset_dir, "dataset folder (shared/spec/dataset.md)")->required();
  app.add_option("--config", config_path,
                 "YAML overriding evaluation options: keys as in config/ground_server.yaml "
                 "(features, estimator, map, place_db, ...), and `air` with the options of "
                 "config/air_agent.yaml; the effective values are logged at start");
  app.add_option("--out", out_dir,
                 "output folder (report.json, <agent>_mapped.tum, <agent>_estimates.csv, plots)");
  app.add_option("--keypoints", keypoints, "override: keypoints per keyframe (both agents)");
  app.add_option("--encoding", encoding,
                 "override: descriptor encoding float32|float16|int8|bits4");
  app.add_option("--budget-mbps", budget, "override: air link budget in Mbit/s (0 = unlimited)");
  app.add_option("--link-loss", link_loss,
                 "override: probability that an IP packet of the air link is lost (0-1)");
  app.add_option("--max-part-bytes", max_part_bytes,
                 "override: split keyframes into parts of at most this many IPv4 bytes (0: whole)");
  app.add_option("--solver", solver, "override: initial solver four_dof|epnp");
  app.add_flag("--no-stage1", no_stage1, "ablation: skip the UGV window BA (r_GC)");
  app.add_flag("--no-reprojection", no_reprojection, "ablation: stage 2 without r_CGCA");
  app.add_flag("--no-consistency", no_consistency, "ablation: stage 2 without r_WAWG");
  app.add_flag("--no-plots", no_plots, "skip the PNG plots");
  app.add_option("--duration", duration, "evaluate only the first N seconds");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error");
  CLI11_PARSE(app, argc, argv);

  ag::LoggingOptions logging;
  logging.level = log_level;
  ag::SetupLogging("evaluate", logging);
  try {
    ag::EvaluateOptions options = config_path.empty()
                                      ? ag::EvaluateOptions{}
                                      : ag::LoadOptionsFile<ag::EvaluateOptions>(config_path);
    if (keypoints > 0) {
      options.features.top_k = keypoints;
      options.air.governor.max_keypoints = keypoints;
      options.air.governor.min_keypoints = std::min(options.air.governor.min_keypoints, keypoints);
    }
    if (!encoding.empty()) options.air.governor.encodings = {encoding};
    if (budget >= 0) options.air.governor.budget_mbps = budget;
    if (link_loss >= 0) options.link_loss = link_loss;
    if (max_part_bytes >= 0) options.air.max_part_bytes = max_part_bytes;
    if (!solver.empty()) options.estimator.ransac.solver = solver;
    if (no_stage1) options.estimator.use_stage1 = false;
    if (no_reprojection) options.estimator.stage2.use_reprojection = false;
    if (no_consistency) options.estimator.stage2.use_consistency = false;
    if (duration > 0) options.max_duration_s = duration;
    ag::CheckOptions(options);
    spdlog::info("effective configuration:\n{}", ag::OptionsToString(options));
    ag::LogLoadedBlas();

    const ag::Dataset dataset = ag::ReadDataset(dataset_dir);
    std::filesystem::create_directories(out_dir);
    const bool tty = isatty(STDERR_FILENO) != 0;
    int last_percent = -1;
    const ag::EvaluationResult result =
        ag::Evaluate(dataset, options, [&](double done, double total) {
          if (!tty || total <= 0) return;
          const int percent = static_cast<int>(100.0 * done / total);
          if (percent == last_percent) return;
          last_percent = percent;
          const int bar = percent * 40 / 100;
          std::fprintf(stderr, "\r[%.*s%*s] %3d%%  %.1f / %.1f s", bar,
                       "########################################", 40 - bar, "", percent, done,
                       total);
          std::fflush(stderr);
        });
    if (tty) std::fprintf(stderr, "\n");
    const std::string prefix = out_dir + "/";
    std::ofstream(prefix + "report.json") << result.report.dump(2) << "\n";
    ag::WriteTrajectoryOutputs(dataset, result, prefix, !no_plots);
    for (const auto& [name, agent] : result.report["agents"].items()) {
      const nlohmann::json& link = agent["link"];
      spdlog::info("{}: link: {} of {} IP packets lost; {} keyframes stored, {} keypoints", name,
                   link["ip_packets_lost"].get<int64_t>(), link["ip_packets"].get<int64_t>(),
                   link["keyframes_stored"].get<int64_t>(),
                   link["keypoints_stored"].get<int64_t>());
      if (agent["final"]["translation_error_m"].is_null()) {
        spdlog::info("{}: {} packets, {:.3f} Mbps mean, {} fixes, no final error", name,
                     agent["packets_sent"].get<int64_t>(),
                     agent["bandwidth_mbps"]["mean"].get<double>(), agent["fixes"].get<int64_t>());
      } else {
        spdlog::info(
            "{}: {} packets, {:.3f} Mbps mean, {} fixes, final error {:.4f} m {:.3f} deg, "
            "{} false fixes",
            name, agent["packets_sent"].get<int64_t>(),
            agent["bandwidth_mbps"]["mean"].get<double>(), agent["fixes"].get<int64_t>(),
            agent["final"]["translation_error_m"].get<double>(),
            agent["final"]["yaw_error_deg"].get<double>(), agent["false_fixes"].get<int64_t>());
      }
    }
    spdlog::info("success: {}; report: {}report.json", result.report["success"].get<bool>(),
                 prefix);
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
}
