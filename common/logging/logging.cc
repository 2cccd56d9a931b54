#include "common/logging/logging.h"

#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/stdout_sinks.h>

#include <memory>
#include <vector>

#include "common/core/error.h"

namespace ag {

void LoggingOptions::Check() const {
  CheckOption(spdlog::level::from_str(level) != spdlog::level::off || level == "off", "level",
              "must be one of trace, debug, info, warn, error, critical, off; got '" + level + "'");
}

void SetupLogging(const std::string& program, const LoggingOptions& options) {
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

}  // namespace ag
