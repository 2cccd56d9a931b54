#pragma once

#include <spdlog/spdlog.h>

#include <string>

namespace ag {

/// Logging set-up shared by the daemons and tools.
struct LoggingOptions {
  std::string level = "info";  ///< trace, debug, info, warn, error, critical, off
  std::string file;            ///< also log to this file when not empty
  bool color = true;           ///< colour on a terminal

  template <class V>
  void VisitFields(V& v) {
    v("level", level);
    v("file", file);
    v("color", color);
  }
  void Check() const;
};

/// Installs the default spdlog logger named `program`: stderr (coloured on a
/// terminal) plus an optional file, pattern "[time] [program] [level] msg".
/// Safe to call more than once (the last call wins).
void SetupLogging(const std::string& program, const LoggingOptions& options = {});

/// What this process has used so far, for a daemon's last log line:
/// "CPU 12.3 s user+system over 61.0 s (20% of one core), peak RSS 310 MB".
/// Wall time counts from the first call (made early by SetupLogging).
std::string ResourceUsage();

}  // namespace ag
