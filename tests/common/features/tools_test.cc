// The feature tools run as a user runs them: tools/fetch_xfeat_model.sh
// (--from only: no network here) and the train_codebook binary.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/features/vlad.h"
#include "tests/support/test_support.h"
#include "tools/train_codebook/procedural_images.h"

namespace ag {
namespace {

namespace fs = std::filesystem;

/// Runs a shell command, its output into `log`; returns the exit status.
int RunShell(const std::string& command, const std::string& log) {
  const int status = std::system((command + " >" + log + " 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string FetchScript() { return test::SourceDir() + "/tools/fetch_xfeat_model.sh"; }

TEST(FetchXFeatModelTest, InstallsACheckedCopyOfTheSharedModel) {
  AG_REQUIRE_SHARED(model, "models/xfeat.onnx");
  test::TempDir dir;
  const std::string dest = dir / "models";
  ASSERT_EQ(RunShell("bash " + FetchScript() + " --from " + model + " --dest " + dest, dir / "log"),
            0)
      << ReadText(dir / "log");
  EXPECT_EQ(fs::file_size(dest + "/xfeat.onnx"), fs::file_size(model));
  EXPECT_NE(ReadText(dir / "log").find("sha256 ok"), std::string::npos) << ReadText(dir / "log");
  EXPECT_EQ(std::distance(fs::directory_iterator(dest), fs::directory_iterator()), 1)
      << "no temporary file left behind";
}

TEST(FetchXFeatModelTest, RefusesAFileWithAnotherChecksum) {
  test::TempDir dir;
  std::ofstream(dir / "fake.onnx") << "not the XFeat model";
  const std::string dest = dir / "models";
  EXPECT_NE(RunShell("bash " + FetchScript() + " --from " + (dir / "fake.onnx") + " --dest " + dest,
                     dir / "log"),
            0);
  EXPECT_NE(ReadText(dir / "log").find("sha256 mismatch"), std::string::npos)
      << ReadText(dir / "log");
  EXPECT_FALSE(fs::exists(dest + "/xfeat.onnx"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dest), fs::directory_iterator()), 0)
      << "no temporary file left behind";
  EXPECT_NE(
      RunShell("bash " + FetchScript() + " --from " + (dir / "absent.onnx") + " --dest " + dest,
               dir / "log"),
      0);
  EXPECT_NE(RunShell("bash " + FetchScript() + " --bogus", dir / "log"), 0);
}

TEST(TrainCodebookToolTest, TrainsAReadableDeterministicCodebook) {
  test::TempDir dir;
  fs::create_directory(dir / "images");
  for (int i = 0; i < 3; ++i) {
    cv::imwrite(dir / ("images/" + std::to_string(i) + ".png"),
                MakeProceduralImage({400, 300}, 900 + i));
  }
  std::ofstream(dir / "images/notes.txt") << "not an image";
  const std::string base = std::string(AG_TRAIN_CODEBOOK_BIN) + " --backend sift --top-k 200 " +
                           "--images " + (dir / "images") + " --procedural 2 --seed 5 -o ";
  ASSERT_EQ(RunShell(base + (dir / "a.yaml"), dir / "log"), 0) << ReadText(dir / "log");
  ASSERT_EQ(RunShell(base + (dir / "b.yaml"), dir / "log"), 0) << ReadText(dir / "log");
  const VladCodebook a = ReadVladCodebook(dir / "a.yaml");
  EXPECT_EQ(a.descriptor_type, "sift");
  EXPECT_EQ(a.clusters(), 4);  // 512 / 128
  EXPECT_EQ(a.dim(), 128);
  EXPECT_NE(a.note.find("5 images"), std::string::npos) << a.note;
  EXPECT_EQ(ReadText(dir / "a.yaml"), ReadText(dir / "b.yaml")) << "same inputs, same file";

  // Nothing to train on is an error, not an empty file.
  EXPECT_NE(RunShell(std::string(AG_TRAIN_CODEBOOK_BIN) + " -o " + (dir / "c.yaml"), dir / "log"),
            0);
  EXPECT_FALSE(fs::exists(dir / "c.yaml"));

  const auto model = test::SharedPath("models/xfeat.onnx");
  if (!model) {
    GTEST_SKIP() << "needs ../shared/models/xfeat.onnx for the XFeat codebook; SIFT part passed";
  }
  ASSERT_EQ(RunShell(std::string(AG_TRAIN_CODEBOOK_BIN) + " --model " + *model +
                         " --procedural 3 --top-k 256 -o " + (dir / "x.yaml"),
                     dir / "log"),
            0)
      << ReadText(dir / "log");
  const VladCodebook x = ReadVladCodebook(dir / "x.yaml");
  EXPECT_EQ(x.descriptor_type, "xfeat");
  EXPECT_EQ(x.vlad_dim(), 512);
}

}  // namespace
}  // namespace ag
