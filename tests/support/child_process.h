#pragma once

// Runs a program as a child process (no shell), so tests can signal it and
// wait for it with a bound on time.

#include <sys/types.h>

#include <optional>
#include <string>
#include <vector>

namespace ag::test {

/// How a child ended.
struct ExitStatus {
  bool exited = false;  ///< returned from main / called exit
  int code = -1;        ///< exit code when exited
  int signal = 0;       ///< the signal that killed it otherwise
};

class ChildProcess {
 public:
  /// Starts argv[0] (a path) with argv; stdout and stderr both go to
  /// `output_path`. Throws std::runtime_error when it cannot be started.
  ChildProcess(const std::vector<std::string>& argv, const std::string& output_path);
  /// Kills (SIGKILL) and reaps the child if it is still running.
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  bool Running();
  void Signal(int sig);
  /// Waits at most timeout_s for the child to end; nullopt if it has not.
  std::optional<ExitStatus> WaitFor(double timeout_s);

 private:
  pid_t pid_ = -1;
  std::optional<ExitStatus> status_;
};

/// The whole content of a file ("" when absent).
std::string ReadFileText(const std::string& path);

/// Polls `path` (every 20 ms, at most timeout_s) until its content contains
/// `text`; stops early when `child` (if given) has ended. True when found.
bool WaitForText(const std::string& path, const std::string& text, double timeout_s,
                 ChildProcess* child = nullptr);

}  // namespace ag::test
