// air_agent: the UAV side. Per keyframe it sends learned keypoints and
// descriptors, a global place descriptor and the VIO camera pose in one
// bandwidth-budgeted LCM packet (or, for a lossy link, in parts of one IP
// packet each).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdint>

#include "air_agent/agent/air_agent_app.h"
#include "common/config/options.h"
#include "common/logging/logging.h"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"air_agent: UAV keyframe sender (features + global descriptor + VIO pose over LCM)"};
  std::string config_path, dataset_dir, dataset_agent, agent, lcm_url, model, log_level,
      calibration;
  double speed = 1.0, budget = -1;
  int keypoints = 0;
  int64_t max_part_bytes = -1;
  bool print_config = false;
  app.add_option("--config", config_path, "YAML options (see config/air_agent.yaml)");
  app.add_option("--dataset", dataset_dir,
                 "replay an air agent of this dataset instead of live LCM input");
  app.add_option("--agent", agent,
                 "agent name (channel suffix); with --dataset also the agent replayed");
  app.add_option("--dataset-agent", dataset_agent,
                 "air agent of the dataset to replay (default: --agent)");
  app.add_option("--calibration", calibration,
                 "live mode: the camera's calibration.yaml (dataset format; else "
                 "calibration_file in --config)");
  app.add_option("--speed", speed, "dataset replay speed factor; 0 = as fast as possible")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--budget-mbps", budget, "link budget in Mbit/s (0 = unlimited)");
  app.add_option("--keypoints", keypoints, "keypoints per keyframe (top-k)");
  app.add_option("--max-part-bytes", max_part_bytes,
                 "split keyframes into parts of at most this many IPv4 bytes for a lossy link "
                 "(1500: one IP packet each; 0: whole keyframes)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--model", model,
                 "XFeat ONNX model (else $AG_XFEAT_MODEL; absent: SIFT fallback)");
  app.add_option("--lcm-url", lcm_url,
                 "LCM provider URL (default: $LCM_DEFAULT_URL or LCM's default)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error");
  app.add_flag("--print-config", print_config, "print the effective configuration and exit");
  CLI11_PARSE(app, argc, argv);

  try {
    ag::AirAgentOptions options = config_path.empty()
                                      ? ag::AirAgentOptions{}
                                      : ag::LoadOptionsFile<ag::AirAgentOptions>(config_path);
    if (!agent.empty()) options.agent = agent;
    if (!lcm_url.empty()) options.lcm_url = lcm_url;
    if (!model.empty()) options.features.model_path = model;
    if (!calibration.empty()) options.calibration_file = calibration;
    if (!log_level.empty()) options.logging.level = log_level;
    if (budget >= 0) options.frontend.governor.budget_mbps = budget;
    if (max_part_bytes >= 0) options.frontend.max_part_bytes = max_part_bytes;
    if (keypoints > 0) {
      options.features.top_k = keypoints;
      options.frontend.governor.max_keypoints = keypoints;
      options.frontend.governor.min_keypoints =
          std::min(options.frontend.governor.min_keypoints, keypoints);
    }
    ag::CheckOptions(options);
    if (print_config) {
      std::printf("%s\n", ag::OptionsToString(options).c_str());
      return 0;
    }
    ag::SetupLogging("air_agent", options.logging);
    spdlog::info("effective configuration:\n{}", ag::OptionsToString(options));
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    ag::AirAgentApp agent_app(options);
    if (!dataset_dir.empty()) {
      agent_app.RunDataset(dataset_dir, dataset_agent.empty() ? options.agent : dataset_agent,
                           speed, g_stop);
    } else {
      agent_app.RunLive(g_stop);
    }
    spdlog::info("air_agent stopped{}; {}", g_stop ? " (signal)" : " (end of data)",
                 ag::ResourceUsage());
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
}
