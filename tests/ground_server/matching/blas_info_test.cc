#include "ground_server/matching/blas_info.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>

#include "ground_server/matching/descriptor_matcher.h"

namespace ag {
namespace {

TEST(BlasInfoTest, NamesTheLibraryTheMatcherMultipliesWith) {
  // OpenCV's core links the system BLAS, so matching has it loaded.
  cv::Mat a(128, 64, CV_32F);
  cv::randu(a, -1, 1);
  for (int i = 0; i < a.rows; ++i) cv::normalize(a.row(i), a.row(i));
  EXPECT_EQ(MatchDescriptors(a, a, MatcherOptions{}).size(), 128u);
  const BlasInfo info = LoadedBlas();
  std::printf("BLAS: %s%s%s\n", info.library.empty() ? "(none)" : info.library.c_str(),
              info.warning.empty() ? "" : "\nwarning: ", info.warning.c_str());
  // Debian's OpenCV is built against the system BLAS, so one is loaded.
  ASSERT_FALSE(info.library.empty());
  EXPECT_TRUE(std::filesystem::exists(info.library)) << info.library;
  EXPECT_EQ(info.warning, BlasWarning(info.library));
}

TEST(BlasInfoTest, WarnsAboutTheSlowOnesOnly) {
  const std::string atlas = BlasWarning("/usr/lib/x86_64-linux-gnu/atlas/libblas.so.3");
  EXPECT_NE(atlas.find("ATLAS"), std::string::npos) << atlas;
  EXPECT_NE(atlas.find("libopenblas0-serial"), std::string::npos) << atlas;
  const std::string reference = BlasWarning("/usr/lib/aarch64-linux-gnu/blas/libblas.so.3");
  EXPECT_NE(reference.find("reference BLAS"), std::string::npos) << reference;
  EXPECT_EQ(BlasWarning("/usr/lib/x86_64-linux-gnu/openblas-serial/libblas.so.3"), "");
  EXPECT_EQ(BlasWarning("/usr/lib/x86_64-linux-gnu/openblas-pthread/libblas.so.3"), "");
  EXPECT_EQ(BlasWarning("/usr/lib/x86_64-linux-gnu/blis-serial/libblas.so.3"), "");
  EXPECT_EQ(BlasWarning(""), "");
}

}  // namespace
}  // namespace ag
