#include "tests/support/test_support.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <stdexcept>

namespace fs = std::filesystem;

namespace ag::test {

std::optional<std::string> SharedDir() {
  for (const char* var : {"AG_SHARED_DIR", "AG_DEFAULT_SHARED_DIR"}) {
    const char* value = std::getenv(var);
    if (value != nullptr && *value != '\0' && fs::is_directory(value)) {
      return fs::canonical(value).string();
    }
  }
#ifdef AG_DEFAULT_SHARED_DIR_PATH
  if (fs::is_directory(AG_DEFAULT_SHARED_DIR_PATH))
    return fs::canonical(AG_DEFAULT_SHARED_DIR_PATH).string();
#endif
  return std::nullopt;
}

std::optional<std::string> SharedPath(const std::string& relative) {
  const auto dir = SharedDir();
  if (!dir) return std::nullopt;
  const fs::path path = fs::path(*dir) / relative;
  if (!fs::exists(path)) return std::nullopt;
  return path.string();
}

std::string SourceDir() { return AG_SOURCE_DIR_PATH; }
std::string BuildDir() { return AG_BUILD_DIR_PATH; }

TempDir::TempDir() {
  std::random_device rd;
  for (int attempt = 0; attempt < 100; ++attempt) {
    const fs::path candidate =
        fs::temp_directory_path() / ("ag_test_" + std::to_string(rd()) + std::to_string(rd()));
    if (fs::create_directory(candidate)) {
      path_ = candidate.string();
      return;
    }
  }
  throw std::runtime_error("cannot create a temporary directory");
}

TempDir::~TempDir() {
  const char* keep = std::getenv("AG_KEEP_TEST_DIRS");
  if (keep != nullptr && *keep != '\0' && std::string(keep) != "0") {
    std::fprintf(stderr, "AG_KEEP_TEST_DIRS: kept %s\n", path_.c_str());
    return;
  }
  std::error_code ec;
  fs::remove_all(path_, ec);
}

}  // namespace ag::test
