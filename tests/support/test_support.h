#pragma once

#include <optional>
#include <string>

namespace ag::test {

/// The ../shared folder (data, models), from $AG_SHARED_DIR or, failing
/// that, the checkout's sibling folder that CMake recorded. Empty when absent.
std::optional<std::string> SharedDir();

/// A path below SharedDir(), or empty when the shared folder or the file is
/// absent.
std::optional<std::string> SharedPath(const std::string& relative);

/// The source checkout and the build folder this test was built in.
std::string SourceDir();
std::string BuildDir();

/// A fresh empty temporary directory, removed by the destructor.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

}  // namespace ag::test

/// Skips the current test with a message naming what is missing when a file
/// of ../shared is absent; otherwise binds `var` to its path.
#define AG_REQUIRE_SHARED(var, relative)                                                  \
  const auto var##_opt = ::ag::test::SharedPath(relative);                                \
  if (!var##_opt) {                                                                       \
    GTEST_SKIP() << "needs ../shared/" << (relative)                                      \
                 << " (set AG_SHARED_DIR to the shared folder); not found, test skipped"; \
  }                                                                                       \
  const std::string& var = *var##_opt
