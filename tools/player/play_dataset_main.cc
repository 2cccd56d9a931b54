// tools/play_dataset: publishes a dataset's sensor streams on the LCM channels
// air_agent (live mode) and ground_server read, merged in time order.
//
//   tools/play_dataset --dataset /tmp/small                 # real time, every agent
//   tools/play_dataset --dataset /tmp/small --speed 0 --no-ground --agents uav1
//
// Exit status: 0 when the data was played (also when stopped by SIGINT or
// SIGTERM), 1 on an unreadable dataset, invalid options or no LCM; CLI11's
// codes for bad arguments. The summary (messages and bytes per channel) goes
// to stdout, the log to stderr.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>

#include "common/config/options.h"
#include "common/dataset/dataset.h"
#include "tools/player/dataset_player.h"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "play_dataset: publishes a dataset's camera, odometry and LiDAR streams over LCM for "
      "air_agent (live mode) and ground_server, merged in time order"};
  std::string dataset_dir, config_path, lcm_url, log_level;
  double speed = 1, max_rate_hz = 0, max_mbps = 0, start_s = 0, duration_s = 0;
  std::vector<std::string> agents;
  bool no_ground = false, no_air = false, align_starts = false, print_config = false;
  app.add_option("--dataset", dataset_dir, "dataset folder (shared/spec/dataset.md)");
  app.add_option("--config", config_path, "YAML player options (keys as --print-config shows)");
  app.add_option("--speed", speed,
                 "1 = real time, 2 = twice as fast, 0 = as fast as the limits allow")
      ->check(CLI::NonNegativeNumber);
  const ag::DatasetPlayerOptions defaults;
  app.add_option("--max-rate-hz", max_rate_hz,
                 fmt::format("at most this many messages per second, in every mode (0 = no "
                             "limit; default {})",
                             defaults.max_rate_hz))
      ->check(CLI::NonNegativeNumber);
  app.add_option("--max-mbps", max_mbps,
                 fmt::format("at most this many Mbit/s of LCM payload, in every mode (0 = no "
                             "limit; default {})",
                             defaults.max_mbps))
      ->check(CLI::NonNegativeNumber);
  app.add_option("--agents", agents, "air agents to play, comma separated (default: all)")
      ->delimiter(',');
  app.add_flag("--no-ground", no_ground, "do not play the ground agent (UGV)");
  app.add_flag("--no-air", no_air, "do not play any air agent (UAV)");
  app.add_option("--start-s", start_s, "skip this many seconds from the start of the data")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--duration-s", duration_s, "play this many seconds (0 = to the end)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--align-starts", align_starts,
               "play every air agent from the ground's start (for clocks far apart); "
               "timestamps are unchanged");
  app.add_option("--lcm-url", lcm_url,
                 "LCM provider URL (default: $LCM_DEFAULT_URL or LCM's default)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error");
  app.add_flag("--print-config", print_config, "print the effective configuration and exit");
  CLI11_PARSE(app, argc, argv);
  // Before the (possibly long) dataset reading, so a signal always ends the
  // run through the normal path (summary, exit status 0).
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);

  ag::DatasetPlayerOptions options;
  try {
    if (!config_path.empty()) options = ag::LoadOptionsFile<ag::DatasetPlayerOptions>(config_path);
    if (app.count("--speed")) options.speed = speed;
    if (app.count("--max-rate-hz")) options.max_rate_hz = max_rate_hz;
    if (app.count("--max-mbps")) options.max_mbps = max_mbps;
    if (!agents.empty()) options.agents = agents;
    if (no_ground) options.ground = false;
    if (no_air) options.air = false;
    if (app.count("--start-s")) options.start_s = start_s;
    if (app.count("--duration-s")) options.duration_s = duration_s;
    if (align_starts) options.align_starts = true;
    if (!lcm_url.empty()) options.lcm_url = lcm_url;
    if (!log_level.empty()) options.logging.level = log_level;
    ag::CheckOptions(options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "play_dataset: %s\n", e.what());
    return 1;
  }
  if (print_config) {
    std::printf("%s\n", ag::OptionsToString(options).c_str());
    return 0;
  }
  if (dataset_dir.empty()) {
    std::fprintf(stderr, "play_dataset: --dataset DIR is required (see --help)\n");
    return 1;
  }

  ag::SetupLogging("play_dataset", options.logging);
  try {
    const ag::Dataset dataset = ag::ReadDataset(dataset_dir);
    ag::DatasetPlayer player(dataset, options);
    lcm::LCM lcm(options.lcm_url);
    if (!lcm.good()) {
      throw std::runtime_error("cannot open LCM with url '" + options.lcm_url + "'");
    }
    spdlog::info("effective configuration:\n{}", ag::OptionsToString(options));
    spdlog::info("playing {} messages of {} ({})", player.schedule().size(), dataset_dir,
                 options.speed > 0 ? fmt::format("speed x{}", options.speed)
                                   : "as fast as the rate limits allow");
    const ag::DatasetPlayerStats stats = player.Run(
        [&lcm](const std::string& channel, const std::vector<uint8_t>& bytes) {
          return lcm.publish(channel, bytes.data(), static_cast<unsigned int>(bytes.size())) == 0;
        },
        g_stop);
    std::fputs(ag::FormatSummary(stats).c_str(), stdout);
    std::fflush(stdout);
    if (stats.publish_errors > 0) {
      spdlog::warn("{} messages could not be published", stats.publish_errors);
    }
    spdlog::info("play_dataset stopped{}", g_stop ? " (signal)" : " (end of data)");
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
