// tools/check_dataset (binary dataset_check): validates a dataset against the
// format (../shared/spec/dataset.md) and prints a summary table.
//
//   tools/check_dataset /tmp/kitti            # reads every image and scan
//   tools/check_dataset /tmp/big --quick      # reads a sample of them
//
// Exit status: 0 valid, 1 invalid (the message names file, line and
// problem), 3 valid but with warnings under --strict; CLI11's codes for bad
// arguments.

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "common/core/error.h"
#include "tools/dataset_checker/dataset_check.h"

int main(int argc, char** argv) {
  CLI::App app{"Validates an air-ground dataset (../shared/spec/dataset.md) and summarises it"};
  std::string dir;
  ag::DatasetCheckOptions options;
  bool strict = false;
  app.add_option("dataset", dir, "dataset folder")->required();
  app.add_flag("--quick", options.quick, "read only a sample of the images and scans");
  app.add_option("--samples", options.quick_samples,
                 "with --quick: files read per agent and sensor (default 8)");
  app.add_option("--min-odometry-rate", options.min_odometry_rate_hz,
                 "warn below this odometry rate (Hz, default 9)");
  app.add_flag("--strict", strict, "exit with status 3 when there are warnings");
  CLI11_PARSE(app, argc, argv);
  try {
    const ag::DatasetCheckReport report = ag::CheckDataset(dir, options);
    std::fputs(ag::FormatReport(report).c_str(), stdout);
    if (strict && !report.warnings.empty()) {
      std::printf("RESULT: valid, but with warnings (--strict)\n");
      return 3;
    }
    std::printf("RESULT: valid\n");
  } catch (const ag::InputError& e) {
    std::fprintf(stderr, "INVALID: %s\n", e.what());
    std::printf("RESULT: invalid\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dataset_check failed: %s\n", e.what());
    return 1;
  }
  return 0;
}
