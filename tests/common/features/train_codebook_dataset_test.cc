// train_codebook on a dataset written by the simulator (format v1): every
// agent's images are used.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "common/features/vlad.h"
#include "tests/support/test_support.h"
#include "tools/sim/scenario.h"
#include "tools/sim/simulator.h"

namespace ag {
namespace {

TEST(TrainCodebookToolTest, TrainsOnASimulatedDataset) {
  Scenario scenario = LoadScenario(test::SourceDir() + "/config/scenarios/small.yaml");
  scenario.options.duration_s = 0.3;
  test::TempDir tmp;
  Simulation(scenario, 77).Write(tmp / "ds");
  const std::string command = std::string(AG_TRAIN_CODEBOOK_BIN) +
                              " --backend sift --top-k 300 --dataset " + (tmp / "ds") + " -o " +
                              (tmp / "cb.yaml") + " >" + (tmp / "log") + " 2>&1";
  const int status = std::system(command.c_str());
  std::ifstream log(tmp / "log");
  std::stringstream text;
  text << log.rdbuf();
  ASSERT_EQ(status, 0) << text.str();
  const VladCodebook codebook = ReadVladCodebook(tmp / "cb.yaml");
  EXPECT_EQ(codebook.vlad_dim(), 512);
  EXPECT_NE(codebook.note.find("dataset"), std::string::npos) << codebook.note;
}

}  // namespace
}  // namespace ag
