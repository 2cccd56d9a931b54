// tools/simulate: writes a simulated air-ground dataset (format v1) for a
// scenario and a seed, or a side-by-side air / ground preview PNG.
//
//   tools/simulate --scenario config/scenarios/small.yaml --seed 1 --out /tmp/small
//   tools/simulate --scenario config/scenarios/covisible.yaml --seed 1 --preview preview.png

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "common/core/error.h"
#include "common/logging/logging.h"
#include "tools/sim/scenario.h"
#include "tools/sim/simulator.h"

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // Each frame allocates and frees some 10 MB of image buffers. By default
  // glibc maps blocks that large fresh from the kernel and unmaps them on
  // free, so every frame page-faults them in again (a few % of the run, as
  // system time). Keeping them in the heap reuses the pages.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's maximum on 64-bit
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
#endif
  CLI::App app{"Simulates an air-ground scenario and writes a dataset (../shared/spec/dataset.md)"};
  std::string scenario_path, out_dir, textures_dir, preview_path, log_level = "info";
  uint64_t seed = 1;
  double duration_s = -1.0, preview_time_s = -1.0;
  int threads = 0;
  app.add_option("--scenario", scenario_path, "scenario YAML (config/scenarios/*.yaml)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--seed", seed,
                 "random seed: same seed and scenario give a byte-identical dataset");
  app.add_option("--out", out_dir, "output dataset folder (must not exist or be empty)");
  app.add_option("--textures", textures_dir,
                 "folder of texture images (default: procedural textures)");
  app.add_option("--duration", duration_s, "override the scenario duration (s)")
      ->check(CLI::PositiveNumber);
  app.add_option("--threads", threads, "worker threads (0 = all cores); does not change the output")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--preview", preview_path,
                 "write one PNG with an air view and a ground view of one place");
  app.add_option("--preview-time", preview_time_s,
                 "time of the preview (s; default: best co-visibility)");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  if (out_dir.empty() && preview_path.empty()) {
    std::fprintf(stderr, "simulate: give --out DIR and/or --preview PNG\n");
    return 2;
  }
  ag::LoggingOptions logging;
  logging.level = log_level;
  ag::SetupLogging("simulate", logging);
  try {
    ag::Scenario scenario = ag::LoadScenario(scenario_path);
    if (duration_s > 0) scenario.options.duration_s = duration_s;
    const auto start = std::chrono::steady_clock::now();
    const ag::Simulation simulation(scenario, seed, textures_dir);
    spdlog::info("simulate: scenario '{}' ({:.1f} s, {} air agent(s), {} objects), seed {}",
                 scenario.options.name, scenario.options.duration_s, scenario.air.size(),
                 simulation.world().objects().size(), seed);
    if (!preview_path.empty()) {
      const double tau = simulation.WritePreview(preview_path, preview_time_s);
      spdlog::info("simulate: preview at t = {:.1f} s written to {}", tau, preview_path);
    }
    if (!out_dir.empty()) simulation.Write(out_dir, threads);
    spdlog::info("simulate: done in {:.1f} s",
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  } catch (const ag::InputError& e) {
    spdlog::error("{}", e.what());
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("simulate failed: {}", e.what());
    return 1;
  }
  return 0;
}
