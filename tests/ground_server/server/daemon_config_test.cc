// config/ground_server.yaml documents every ground_server option with its
// default value and a comment (see tests/support/config_file_check.h).
#include <gtest/gtest.h>

#include <fstream>

#include "ground_server/server/ground_server_app.h"
#include "tests/support/config_file_check.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

TEST(GroundServerConfig, FileListsEveryOptionAtItsDefault) {
  test::ExpectConfigFileDocumentsDefaults<GroundServerOptions>(test::SourceDir() +
                                                               "/config/ground_server.yaml");
}

TEST(GroundServerConfig, CheckCatchesAMisspelledKey) {
  // The check itself: a misspelled key, a changed value and a missing
  // comment each fail.
  test::TempDir tmp;
  std::ofstream(tmp / "typo.yaml") << "# x\nwindow_sise: 5\n";
  EXPECT_THROW(ReadOptions<GroundServerOptions>(LoadYamlFile(tmp / "typo.yaml"), "typo.yaml"),
               std::exception);
  std::ofstream(tmp / "plain.yaml") << "# x\nwindow_size: 5\nestimate_period_s: 1\n";
  const std::vector<std::string> missing = test::UncommentedKeys(tmp / "plain.yaml");
  ASSERT_EQ(missing.size(), 1u);
  EXPECT_EQ(missing[0], "line 3: estimate_period_s");
}

TEST(GroundServerConfig, ABadAirAgentsPatternIsAnErrorNamingTheKey) {
  test::TempDir tmp;
  std::ofstream(tmp / "agents.yaml") << "calibration_file: c.yaml\nair_agents: \"uav[0-9\"\n";
  try {
    LoadOptions<GroundServerOptions>(LoadYamlFile(tmp / "agents.yaml"), "agents.yaml");
    FAIL() << "no error for an unbalanced bracket";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("air_agents"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("uav[0-9"), std::string::npos) << e.what();
  }
  GroundServerOptions good;
  good.calibration_file = "c.yaml";
  good.air_agents = "uav1|uav3";
  EXPECT_NO_THROW(CheckOptions(good));
}

}  // namespace
}  // namespace ag
