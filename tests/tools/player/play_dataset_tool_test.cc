// The play_dataset binary and its wrapper script: --help, clear errors with a
// non-zero status, a whole run with its per-channel summary, and a clean exit
// (status 0, summary printed) on SIGTERM and SIGINT. Every run uses memq://,
// LCM's in-process provider: nothing reaches any network.

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <regex>
#include <thread>

#include "common/dataset/dataset.h"
#include "tests/support/child_process.h"
#include "tests/support/playback_fixture.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

struct PlayerRun {
  test::ExitStatus status;
  std::string output;
};

/// Runs play_dataset to its end (at most 60 s).
PlayerRun RunPlayer(const std::vector<std::string>& args, const std::string& log) {
  std::vector<std::string> argv = {AG_PLAY_DATASET_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  test::ChildProcess child(argv, log);
  const auto status = child.WaitFor(60);
  EXPECT_TRUE(status.has_value()) << "play_dataset did not end in 60 s";
  return {status.value_or(test::ExitStatus{}), test::ReadFileText(log)};
}

/// The message count of `channel` in the summary table.
int64_t SummaryCount(const std::string& output, const std::string& channel) {
  std::smatch m;
  if (!std::regex_search(output, m, std::regex("\\n  " + channel + " +([0-9]+) +[0-9]+\\n"))) {
    return -1;
  }
  return std::stoll(m[1]);
}

TEST(PlayDatasetTool, HelpListsTheOptions) {
  test::TempDir tmp;
  const PlayerRun run = RunPlayer({"--help"}, tmp / "log.txt");
  EXPECT_TRUE(run.status.exited);
  EXPECT_EQ(run.status.code, 0) << run.output;
  for (const char* option :
       {"--dataset", "--speed", "--max-rate-hz", "--max-mbps", "--agents", "--no-ground",
        "--no-air", "--start-s", "--duration-s", "--align-starts", "--lcm-url", "--print-config"}) {
    EXPECT_NE(run.output.find(option), std::string::npos) << option << "\n" << run.output;
  }
}

TEST(PlayDatasetTool, ErrorsAreClearAndNonZero) {
  test::TempDir tmp;
  PlayerRun run = RunPlayer({"--dataset", tmp / "nowhere", "--lcm-url", "memq://"}, tmp / "a.txt");
  EXPECT_EQ(run.status.code, 1) << run.output;
  EXPECT_NE(run.output.find(tmp / "nowhere"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("does not exist"), std::string::npos) << run.output;

  run = RunPlayer({"--lcm-url", "memq://"}, tmp / "b.txt");
  EXPECT_EQ(run.status.code, 1) << run.output;
  EXPECT_NE(run.output.find("--dataset DIR is required"), std::string::npos) << run.output;

  const std::string dataset = test::WritePlaybackFixture(tmp / "dataset");
  run = RunPlayer({"--dataset", dataset, "--agents", "uav1,uav7", "--lcm-url", "memq://"},
                  tmp / "c.txt");
  EXPECT_EQ(run.status.code, 1) << run.output;
  EXPECT_NE(run.output.find("'uav7' is not an air agent"), std::string::npos) << run.output;

  run = RunPlayer({"--dataset", dataset, "--no-ground", "--no-air"}, tmp / "d.txt");
  EXPECT_EQ(run.status.code, 1) << run.output;
  EXPECT_NE(run.output.find("nothing to play"), std::string::npos) << run.output;

  run = RunPlayer({"--dataset", dataset, "--speed", "-1"}, tmp / "e.txt");
  EXPECT_NE(run.status.code, 0) << run.output;
}

TEST(PlayDatasetTool, PlaysEverythingAndPrintsTheSummary) {
  test::TempDir tmp;
  const std::string dataset = test::WritePlaybackFixture(tmp / "dataset");
  const Dataset ds = ReadDataset(dataset);
  const PlayerRun run =
      RunPlayer({"--dataset", dataset, "--speed", "0", "--agents", "uav2", "--lcm-url", "memq://"},
                tmp / "log.txt");
  EXPECT_TRUE(run.status.exited);
  ASSERT_EQ(run.status.code, 0) << run.output;
  EXPECT_EQ(SummaryCount(run.output, "AG_UGV_IMAGE"), static_cast<int64_t>(ds.ground.images.size()))
      << run.output;
  EXPECT_EQ(SummaryCount(run.output, "AG_UGV_POINTS"),
            static_cast<int64_t>(ds.ground.scans.size()));
  EXPECT_EQ(SummaryCount(run.output, "AG_UGV_ODOMETRY"),
            static_cast<int64_t>(ds.ground.odometry.size()));
  EXPECT_EQ(SummaryCount(run.output, "AG_AIR_IMAGE_uav2"),
            static_cast<int64_t>(ds.air.at("uav2").images.size()));
  EXPECT_EQ(SummaryCount(run.output, "AG_AIR_ODOMETRY_uav2"),
            static_cast<int64_t>(ds.air.at("uav2").odometry.size()));
  EXPECT_EQ(SummaryCount(run.output, "AG_AIR_IMAGE_uav1"), -1) << "not selected";
  EXPECT_NE(run.output.find("play_dataset stopped (end of data)"), std::string::npos);
}

TEST(PlayDatasetTool, WrapperScriptRunsTheBuiltBinary) {
  test::TempDir tmp;
  setenv("AG_BUILD_DIR", test::BuildDir().c_str(), 1);
  test::ChildProcess child({AG_PLAY_DATASET_SCRIPT, "--print-config", "--speed", "3"},
                           tmp / "log.txt");
  const auto status = child.WaitFor(30);
  ASSERT_TRUE(status.has_value());
  const std::string output = test::ReadFileText(tmp / "log.txt");
  EXPECT_EQ(status->code, 0) << output;
  EXPECT_NE(output.find("speed: 3"), std::string::npos) << output;

  setenv("AG_BUILD_DIR", (tmp / "no_build").c_str(), 1);
  test::ChildProcess missing({AG_PLAY_DATASET_SCRIPT, "--help"}, tmp / "log2.txt");
  const auto missing_status = missing.WaitFor(30);
  ASSERT_TRUE(missing_status.has_value());
  EXPECT_EQ(missing_status->code, 1);
  EXPECT_NE(test::ReadFileText(tmp / "log2.txt").find("is not built"), std::string::npos);
  unsetenv("AG_BUILD_DIR");
}

class PlayDatasetSignalTest : public ::testing::TestWithParam<int> {};

TEST_P(PlayDatasetSignalTest, StopsCleanlyWithTheSummary) {
  test::TempDir tmp;
  const std::string dataset = test::WritePlaybackFixture(tmp / "dataset");
  // 1 s of data at a quarter of real time: 4 s, far longer than the wait below.
  test::ChildProcess child(
      {AG_PLAY_DATASET_BINARY, "--dataset", dataset, "--speed", "0.25", "--lcm-url", "memq://"},
      tmp / "log.txt");
  ASSERT_TRUE(test::WaitForText(tmp / "log.txt", "playing ", 20, &child))
      << test::ReadFileText(tmp / "log.txt");
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // some messages out
  ASSERT_TRUE(child.Running()) << test::ReadFileText(tmp / "log.txt");
  const auto sent = std::chrono::steady_clock::now();
  child.Signal(GetParam());
  const auto status = child.WaitFor(5);
  const double exit_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  const std::string output = test::ReadFileText(tmp / "log.txt");
  ASSERT_TRUE(status.has_value()) << "still running 5 s after the signal\n" << output;
  EXPECT_TRUE(status->exited) << "killed by signal " << status->signal << "\n" << output;
  EXPECT_EQ(status->code, 0) << output;
  EXPECT_LT(exit_s, 3.0) << "the player checks for the signal at least every 100 ms";
  EXPECT_NE(output.find("stopped before the end"), std::string::npos) << output;
  EXPECT_NE(output.find("play_dataset stopped (signal)"), std::string::npos) << output;
  EXPECT_GT(SummaryCount(output, "AG_UGV_ODOMETRY"), 0) << output;
}

INSTANTIATE_TEST_SUITE_P(Signals, PlayDatasetSignalTest, ::testing::Values(SIGTERM, SIGINT),
                         [](const ::testing::TestParamInfo<int>& info) {
                           return info.param == SIGTERM ? std::string("SIGTERM")
                                                        : std::string("SIGINT");
                         });

}  // namespace
}  // namespace ag
