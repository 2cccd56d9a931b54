#include "common/config/options.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "common/logging/logging.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

struct InnerOptions {
  double voxel_size_m = 0.1;  ///< voxel edge (m)
  std::vector<int> sizes = {1, 2};
  template <class V>
  void VisitFields(V& v) {
    v("voxel_size_m", voxel_size_m);
    v("sizes", sizes);
  }
  void Check() const { CheckOption(voxel_size_m > 0, "voxel_size_m", "must be > 0"); }
};

struct OuterOptions {
  int top_k = 1024;
  bool enabled = true;
  std::string name = "default";
  InnerOptions map;
  LoggingOptions logging;
  template <class V>
  void VisitFields(V& v) {
    v("top_k", top_k);
    v("enabled", enabled);
    v("name", name);
    v("map", map);
    v("logging", logging);
  }
  void Check() const { CheckOption(top_k > 0, "top_k", "must be positive"); }
};

InputError LoadError(const std::string& yaml) {
  try {
    LoadOptions<OuterOptions>(YAML::Load(yaml), "fixture.yaml");
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for: " << yaml;
  return InputError(InputErrorKind::kBadValue, "", 0, "");
}

TEST(OptionsTest, DefaultsKeptAndValuesRead) {
  const auto o = LoadOptions<OuterOptions>(
      YAML::Load("top_k: 256\nmap: {voxel_size_m: 0.2, sizes: [3, 4, 5]}\n"), "f.yaml");
  EXPECT_EQ(o.top_k, 256);
  EXPECT_TRUE(o.enabled);
  EXPECT_EQ(o.name, "default");
  EXPECT_DOUBLE_EQ(o.map.voxel_size_m, 0.2);
  EXPECT_EQ(o.map.sizes, (std::vector<int>{3, 4, 5}));
  EXPECT_EQ(o.logging.level, "info");
}

TEST(OptionsTest, EmptyNodeGivesDefaults) {
  const auto o = LoadOptions<OuterOptions>(YAML::Node(), "f.yaml");
  EXPECT_EQ(o.top_k, 1024);
}

TEST(OptionsTest, UnknownKeysAreRejectedWithTheirName) {
  InputError e = LoadError("top_k: 5\ntopk: 6\n");
  EXPECT_EQ(e.kind(), InputErrorKind::kUnknownKey);
  EXPECT_EQ(e.line(), 2);
  EXPECT_NE(std::string(e.what()).find("'topk'"), std::string::npos) << e.what();
  e = LoadError("map:\n  voxel_size: 0.3\n");
  EXPECT_EQ(e.kind(), InputErrorKind::kUnknownKey);
  EXPECT_NE(std::string(e.what()).find("'map.voxel_size'"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("fixture.yaml:2"), std::string::npos) << e.what();
}

TEST(OptionsTest, WrongTypesAndInvalidValuesNameTheField) {
  InputError e = LoadError("top_k: many\n");
  EXPECT_EQ(e.kind(), InputErrorKind::kBadValue);
  EXPECT_NE(std::string(e.what()).find("top_k"), std::string::npos) << e.what();
  e = LoadError("map: {voxel_size_m: -1}\n");
  EXPECT_EQ(e.kind(), InputErrorKind::kBadValue);
  EXPECT_NE(std::string(e.what()).find("map.voxel_size_m must be > 0"), std::string::npos)
      << e.what();
  e = LoadError("top_k: 0\n");
  EXPECT_NE(std::string(e.what()).find("top_k must be positive"), std::string::npos) << e.what();
  e = LoadError("logging: {level: loud}\n");
  EXPECT_NE(std::string(e.what()).find("logging.level"), std::string::npos) << e.what();
  e = LoadError("map: 3\n");
  EXPECT_NE(std::string(e.what()).find("'map' must be a map"), std::string::npos) << e.what();
  e = LoadError("map: {sizes: 3}\n");
  EXPECT_NE(std::string(e.what()).find("'map.sizes' must be a list"), std::string::npos)
      << e.what();
}

TEST(OptionsTest, ReadOptionsRejectsUnknownKeysButLeavesValidationToTheCaller) {
  // An invalid value is read as is (flags may still fix it before Check)...
  const OuterOptions read = ReadOptions<OuterOptions>(YAML::Load("top_k: 0\n"), "fixture.yaml");
  EXPECT_EQ(read.top_k, 0);
  EXPECT_THROW(CheckOptions(read), OptionError);
  // ... but an unknown key is still an error naming it.
  try {
    ReadOptions<OuterOptions>(YAML::Load("top_k: 5\ntopk: 6\n"), "fixture.yaml");
    ADD_FAILURE() << "unknown key accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), InputErrorKind::kUnknownKey);
    EXPECT_NE(std::string(e.what()).find("'topk'"), std::string::npos) << e.what();
  }
}

TEST(OptionsTest, EffectiveConfigRoundTrips) {
  OuterOptions o;
  o.top_k = 77;
  o.map.sizes = {9};
  o.name = "x y";
  const std::string text = OptionsToString(o);
  EXPECT_NE(text.find("top_k: 77"), std::string::npos) << text;
  // Doubles print as the shortest text that reads back exactly.
  EXPECT_NE(text.find("voxel_size_m: 0.1\n"), std::string::npos) << text;
  const auto back = LoadOptions<OuterOptions>(YAML::Load(text), "dump");
  EXPECT_EQ(back.top_k, 77);
  EXPECT_EQ(back.map.sizes, std::vector<int>{9});
  EXPECT_EQ(back.name, "x y");
}

TEST(OptionsTest, FileSectionsAndFileErrors) {
  test::TempDir dir;
  std::ofstream(dir / "c.yaml") << "air:\n  top_k: 3\nground:\n  top_k: 4\n";
  EXPECT_EQ(LoadOptionsFile<OuterOptions>(dir / "c.yaml", "ground").top_k, 4);
  try {
    LoadOptionsFile<OuterOptions>(dir / "none.yaml");
    FAIL() << "no error for a missing file";
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), InputErrorKind::kMissingFile);
  }
  std::ofstream(dir / "broken.yaml") << "a: [1, 2\nb: 3\n";
  try {
    LoadOptionsFile<OuterOptions>(dir / "broken.yaml");
    FAIL() << "no error for broken YAML";
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), InputErrorKind::kMalformedRow);
    EXPECT_NE(std::string(e.what()).find("broken.yaml"), std::string::npos);
  }
}

TEST(LoggingTest, SetupInstallsNamedLogger) {
  LoggingOptions options;
  options.level = "debug";
  SetupLogging("unit_test", options);
  EXPECT_EQ(spdlog::default_logger()->name(), "unit_test");
  EXPECT_EQ(spdlog::default_logger()->level(), spdlog::level::debug);
}

/// CPU seconds in a ResourceUsage() line.
double CpuSeconds(const std::string& usage) {
  const size_t at = usage.find("CPU ");
  EXPECT_NE(at, std::string::npos) << usage;
  return at == std::string::npos ? -1.0 : std::stod(usage.substr(at + 4));
}

TEST(LoggingTest, ResourceUsageCountsCpuTimeAndMemory) {
  const std::string before = ResourceUsage();
  volatile double sink = 0;
  std::vector<double> block(20'000'000, 1.0);  // 160 MB, touched
  for (int pass = 0; pass < 5; ++pass) {
    for (double& x : block) sink = sink + (x += 1e-9);
  }
  const std::string after = ResourceUsage();
  EXPECT_GT(CpuSeconds(after), CpuSeconds(before)) << before << " / " << after;
  EXPECT_NE(after.find("% of one core"), std::string::npos) << after;
  const size_t rss = after.find("peak RSS ");
  ASSERT_NE(rss, std::string::npos) << after;
  EXPECT_GE(std::stoi(after.substr(rss + 9)), 150) << after;
}

}  // namespace
}  // namespace ag
