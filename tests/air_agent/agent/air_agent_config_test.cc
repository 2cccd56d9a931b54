// config/air_agent.yaml documents every air_agent option with its default
// value and a comment (see tests/support/config_file_check.h).
#include <gtest/gtest.h>

#include "air_agent/agent/air_agent_app.h"
#include "tests/support/config_file_check.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

TEST(AirAgentConfig, FileListsEveryOptionAtItsDefault) {
  test::ExpectConfigFileDocumentsDefaults<AirAgentOptions>(test::SourceDir() +
                                                           "/config/air_agent.yaml");
}

}  // namespace
}  // namespace ag
