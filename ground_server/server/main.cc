// ground_server: the UGV side. Estimates T_wa_wg for every air agent from the
// UGV's camera, LiDAR and LIO streams and the UAVs' keyframe packets.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>

#include "common/config/options.h"
#include "common/logging/logging.h"
#include "ground_server/server/ground_server_app.h"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ground_server: air-ground relative localization on the UGV (LCM in, T_wa_wg out)"};
  std::string config_path, calibration, persistence, lcm_url, model, log_level;
  bool print_config = false;
  app.add_option("--config", config_path, "YAML options (see config/ground_server.yaml)");
  app.add_option("--calibration", calibration, "the UGV's calibration.yaml (dataset format)");
  app.add_option("--persistence-dir", persistence,
                 "place database and state survive restarts here");
  app.add_option("--model", model,
                 "XFeat ONNX model (else $AG_XFEAT_MODEL; absent: SIFT fallback)");
  app.add_option("--lcm-url", lcm_url,
                 "LCM provider URL (default: $LCM_DEFAULT_URL or LCM's default)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error");
  app.add_flag("--print-config", print_config, "print the effective configuration and exit");
  CLI11_PARSE(app, argc, argv);
  try {
    // Flags override the file; validation comes after both (a --config
    // without calibration_file is fine with --calibration).
    ag::GroundServerOptions options =
        config_path.empty()
            ? ag::GroundServerOptions{}
            : ag::ReadOptions<ag::GroundServerOptions>(ag::LoadYamlFile(config_path), config_path);
    if (!calibration.empty()) options.calibration_file = calibration;
    if (!persistence.empty()) options.persistence_dir = persistence;
    if (!model.empty()) options.features.model_path = model;
    if (!lcm_url.empty()) options.lcm_url = lcm_url;
    if (!log_level.empty()) options.logging.level = log_level;
    if (print_config) {
      std::printf("%s\n", ag::OptionsToString(options).c_str());
      return 0;
    }
    ag::CheckOptions(options);
    ag::SetupLogging("ground_server", options.logging);
    spdlog::info("effective configuration:\n{}", ag::OptionsToString(options));
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    ag::GroundServerApp server(options);
    server.Run(g_stop);
    spdlog::info("ground_server stopped; {}", ag::ResourceUsage());
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
}
