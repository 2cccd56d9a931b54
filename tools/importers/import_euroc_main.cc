// tools/import_euroc: a EuRoC MAV sequence (ASL layout) -> one air agent of a
// dataset v1. A dataset needs exactly one ground agent and EuRoC has none, so
// the agent goes into an existing dataset, or into a new one whose ground
// agent is copied from another dataset:
//
//   tools/import_euroc MH_01_easy --into /tmp/kitti --agent mh01
//   tools/import_euroc MH_01_easy --out /tmp/mh01 --ground-from /tmp/kitti --agent mh01
//       --drift 0.02 --drift-yaw 0.1 --seed 3

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "common/core/error.h"
#include "common/logging/logging.h"
#include "tools/importers/euroc.h"

int main(int argc, char** argv) {
  CLI::App app{
      "Imports a EuRoC MAV sequence (ASL layout) as an air agent of an air-ground dataset "
      "(../shared/spec/dataset.md)"};
  ag::EurocImportOptions options;
  std::string log_level = "info";
  app.add_option("sequence", options.input, "EuRoC sequence folder (holding mav0/) or mav0")
      ->required();
  app.add_option("--agent", options.agent, "air agent name, [a-z0-9_]+ (default: euroc)");
  app.add_option("--camera", options.camera, "camera folder of mav0 (default: cam0)");
  auto* into = app.add_option("--into", options.into, "add the agent to this existing dataset");
  auto* out =
      app.add_option("--out", options.out_dir, "create this new dataset (needs --ground-from)");
  app.add_option("--ground-from", options.ground_from,
                 "with --out: copy the ground agent from this dataset");
  into->excludes(out);
  app.add_option("--name", options.name, "name of a new dataset (default: the sequence's)");
  app.add_option("--air-offset", options.air_offset,
                 "write T_wa_wg = x,y,z (m),yaw (deg) to groundtruth.yaml, e.g. -5,2,0,30 "
                 "(default: leave groundtruth.yaml as it is)")
      ->delimiter(',')
      ->expected(4);
  app.add_option("--drift", options.drift_m_per_sqrt_s,
                 "odometry = ground truth + random-walk drift, x y z (m/sqrt(s); default 0)");
  app.add_option("--drift-yaw", options.drift_yaw_deg_per_sqrt_s,
                 "random-walk drift of yaw (deg/sqrt(s); default 0)");
  app.add_option("--seed", options.seed, "random seed of the drift");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  ag::LoggingOptions logging;
  logging.level = log_level;
  ag::SetupLogging("import_euroc", logging);
  try {
    const ag::EurocImportSummary summary = ag::ImportEuroc(options);
    spdlog::info("import_euroc: air agent '{}': {} images, {} ground-truth poses", summary.agent,
                 summary.images, summary.poses);
    if (summary.images_outside_groundtruth > 0) {
      spdlog::warn(
          "import_euroc: {} image(s) are timed outside the ground truth (EuRoC's cameras start "
          "before it); imported as they are",
          summary.images_outside_groundtruth);
    }
    spdlog::info("import_euroc: wrote {}", summary.dataset_dir);
  } catch (const ag::InputError& e) {
    spdlog::error("{}", e.what());
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("import_euroc failed: {}", e.what());
    return 1;
  }
  return 0;
}
