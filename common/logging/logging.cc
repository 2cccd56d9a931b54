#include "common/logging/logging.h"

#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <sys/resource.h>

#include <chrono>
#include <memory>
#include <vector>

#include "common/core/error.h"

namespace ag {

void LoggingOptions::Check() const {
  CheckOption(spdlog::level::from_str(level) != spdlog::level::off || level == "off", "level",
              "must be one of trace, debug, info, warn, error, critical, off; got '" + level + "'");
}

void SetupLogging(const std::string& program, const LoggingOptions& options) {
  ResourceUsage();  // starts the wall clock
  std::vector<spdlog::sink_ptr> sinks;
  if (options.color) {
    sinks.push_back(std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
  } else {
    sinks.push_back(std::make_shared<spdlog::sinks::stderr_sink_mt>());
  }
  if (!options.file.empty()) {
    sinks.push_back(std::make_shared<spdlog::sinks::basic_file_sink_mt>(options.file));
  }
  auto logger = std::make_shared<spdlog::logger>(program, sinks.begin(), sinks.end());
  logger->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%n] [%^%l%$] %v");
  logger->set_level(spdlog::level::from_str(options.level));
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(logger);
}

std::string ResourceUsage() {
  using Clock = std::chrono::steady_clock;
  static const Clock::time_point start = Clock::now();
  const double wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return "resource usage unavailable";
  const auto seconds = [](const timeval& tv) { return tv.tv_sec + tv.tv_usec * 1e-6; };
  const double cpu_s = seconds(usage.ru_utime) + seconds(usage.ru_stime);
  return fmt::format("CPU {:.1f} s user+system over {:.1f} s ({:.0f}% of one core), peak RSS {} MB",
                     cpu_s, wall_s, wall_s > 0 ? 100.0 * cpu_s / wall_s : 0.0,
                     usage.ru_maxrss / 1024);  // ru_maxrss is in KiB on Linux
}

}  // namespace ag
