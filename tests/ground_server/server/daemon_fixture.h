#pragma once

// Shared by the ground_server daemon tests: the simulated `small` dataset
// (cached in the build folder: simulating it takes about a minute on two
// busy cores, and three tests use it), the daemons' configuration files,
// and reading what lcm_capture recorded.

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "common/geometry/pose.h"
#include "common/wire/message_codec.h"
#include "lcmtypes/checked_decode.h"
#include "tests/support/child_process.h"
#include "tests/support/test_support.h"
#include "tools/sim/scenario.h"
#include "tools/sim/simulator.h"

namespace ag::test {

/// The `small` scenario lasting duration_s, simulated with `seed`, under
/// <build>/test_data/ (keyed by the scenario's content, so a retuned preset
/// is simulated anew). Concurrent test processes wait for one writer.
inline std::string CachedSmallDataset(double duration_s, uint64_t seed) {
  namespace fs = std::filesystem;
  Scenario scenario = LoadScenario(SourceDir() + "/config/scenarios/small.yaml");
  scenario.options.duration_s = duration_s;
  std::ostringstream key;
  key << std::hex << std::hash<std::string>{}(ScenarioToYaml(scenario)) << "_seed" << std::dec
      << seed;
  const std::string cache = BuildDir() + "/test_data";
  std::string dir = cache + "/small_" + key.str();
  if (fs::exists(dir + "/dataset.yaml")) return dir;
  fs::create_directories(cache);
  const int lock = open((cache + "/.lock").c_str(), O_CREAT | O_RDWR, 0644);
  if (lock >= 0) flock(lock, LOCK_EX);
  if (!fs::exists(dir + "/dataset.yaml")) {
    const std::string tmp = dir + ".tmp" + std::to_string(getpid());
    fs::remove_all(tmp);
    Simulation(scenario, seed).Write(tmp);
    fs::rename(tmp, dir);
  }
  if (lock >= 0) close(lock);  // releases the lock
  return dir;
}

/// YAML for a daemon's `features:` section: XFeat with the shared model when
/// ../shared has it, else SIFT (both daemons must agree).
inline std::string FeaturesYaml() {
  const std::optional<std::string> model = SharedPath("models/xfeat.onnx");
  return model ? "features: {backend: xfeat, model_path: " + *model + "}\n"
               : std::string("features: {backend: sift}\n");
}

/// One row of lcm_capture's index.csv.
struct Captured {
  int64_t recv_utime = 0;
  std::string channel;
  int n = 0;
  int64_t bytes = 0;
  std::string path;  ///< the message's file
};

/// Everything lcm_capture wrote to `dir`, in arrival order.
inline std::vector<Captured> ReadCapture(const std::string& dir) {
  std::vector<Captured> out;
  std::ifstream in(dir + "/index.csv");
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    Captured c;
    std::string field;
    if (!std::getline(ss, field, ',')) continue;
    c.recv_utime = std::stoll(field);
    std::getline(ss, c.channel, ',');
    std::getline(ss, field, ',');
    c.n = std::stoi(field);
    std::getline(ss, field, ',');
    c.bytes = std::stoll(field);
    c.path = dir + "/" + c.channel + "." + std::to_string(c.n) + ".bin";
    out.push_back(c);
  }
  return out;
}

/// Decodes one captured message file; false when it is not a `Msg`.
template <class Msg>
bool DecodeCaptured(const Captured& c, Msg* msg) {
  const std::string bytes = ReadFileText(c.path);
  return DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), msg) > 0;
}

/// The integer printed as `key=<n>` by a test script, or -1.
inline int64_t ScriptValue(const std::string& log, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(log, m, std::regex("(^|\\n)" + key + "=(-?[0-9]+)"))) return -1;
  return std::stoll(m[2]);
}
/// The number printed as `key=<x.y>` by a test script, or -1.
inline double ScriptNumber(const std::string& log, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(log, m, std::regex("(^|\\n)" + key + "=(-?[0-9.]+)"))) return -1;
  return std::stod(m[2]);
}

/// The last line of `log` that contains `tag` ("" if none).
inline std::string LastLineWith(const std::string& log, const std::string& tag) {
  const size_t at = log.rfind(tag);
  if (at == std::string::npos) return "";
  const size_t begin = log.rfind('\n', at);
  const size_t start = begin == std::string::npos ? 0 : begin + 1;
  return log.substr(start, log.find('\n', at) - start);
}

/// The integer after `label` in `line` ("scans 100" -> 100), or -1.
inline int64_t Field(const std::string& line, const std::string& label) {
  std::smatch m;
  if (!std::regex_search(line, m, std::regex(label + " (-?[0-9]+)"))) return -1;
  return std::stoll(m[1]);
}

/// Bash functions the daemon test scripts share: bounded waits, CPU time of
/// a process, and a bounded stop (SIGTERM, then SIGKILL after 10 s) that
/// prints `<name>_status=<exit status>`.
inline const char* kScriptFunctions = R"(set -u
wait_for() {  # file text timeout_s: true once the file contains the text
  local i=0
  while ! grep -q -- "$2" "$1" 2>/dev/null && [ $i -lt $(( $3 * 20 )) ]; do sleep 0.05; i=$((i+1)); done
  grep -q -- "$2" "$1" 2>/dev/null
}
cpu_s() {  # pid: user + system CPU seconds so far
  awk -v hz=$(getconf CLK_TCK) '{printf "%.2f", ($14 + $15) / hz}' /proc/$1/stat 2>/dev/null || echo -1
}
stop() {  # pid name
  kill -TERM $1 2>/dev/null
  local i=0
  while kill -0 $1 2>/dev/null && [ $i -lt 200 ]; do sleep 0.05; i=$((i+1)); done
  kill -KILL $1 2>/dev/null
  wait $1
  echo "$2_status=$?"
}
now() { date +%s.%N; }
)";

}  // namespace ag::test
