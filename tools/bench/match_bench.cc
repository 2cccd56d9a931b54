// match_bench: time of one air-ground descriptor matching (mutual nearest
// neighbour + ratio test) per backend and keypoint count, on the calling
// thread, as the estimator runs it. Prints a table; nothing is asserted
// (tests check that every backend returns the same matches).
//
//   match_bench [--sizes 256,512,1024] [--repeats 20]
//
// Data: unit 64-D descriptors; the UAV set is random, the UGV set holds a
// noisy copy of 60% of it (the rest random), so the ratio test and the
// mutual check see both kinds of rows. Timing does not depend on the values.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <exception>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "common/core/cpu_time.h"
#include "ground_server/matching/descriptor_matcher.h"

namespace ag {
namespace {

cv::Mat RandomUnitRows(int rows, std::mt19937* rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  cv::Mat m(rows, 64, CV_32F);
  for (int r = 0; r < rows; ++r) {
    float* p = m.ptr<float>(r);
    for (int c = 0; c < 64; ++c) p[c] = n(*rng);
    cv::normalize(m.row(r), m.row(r));
  }
  return m;
}

void Run(int n, int repeats) {
  std::mt19937 rng(7);
  const cv::Mat air = RandomUnitRows(n, &rng);
  cv::Mat ugv = RandomUnitRows(n, &rng);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (int r = 0; r < n * 6 / 10; ++r) {
    cv::Mat row = ugv.row(r);
    air.row((r * 7) % n).copyTo(row);
    for (int c = 0; c < 64; ++c) row.at<float>(c) += noise(rng);
    cv::normalize(row, row);
  }
  for (const std::string backend : {"gemm", "faiss", "opencv"}) {
    MatcherOptions options;
    options.backend = backend;
    std::vector<double> ms;
    size_t matches = 0;
    for (int i = 0; i < repeats; ++i) {
      const double start = ThreadCpuMs();
      matches = MatchDescriptors(ugv, air, options).size();
      ms.push_back(ThreadCpuMs() - start);
    }
    std::sort(ms.begin(), ms.end());
    std::printf("| %5d x %-5d | %-7s | %8.2f | %8.2f | %7zu |\n", n, n, backend.c_str(),
                ms[ms.size() / 2], ms.front(), matches);
  }
}

}  // namespace
}  // namespace ag

int main(int argc, char** argv) {
  try {
    CLI::App app("Descriptor matching benchmark: time per backend and keypoint count");
    std::vector<int> sizes = {256, 512, 1024};
    int repeats = 20;
    app.add_option("--sizes", sizes, "keypoints on each side")->delimiter(',');
    app.add_option("--repeats", repeats, "matchings per size and backend")
        ->check(CLI::PositiveNumber);
    CLI11_PARSE(app, argc, argv);
    std::printf("match_bench: 64-D float descriptors, one thread, CPU time of this thread\n");
    std::printf("| UGV x UAV     | backend | med ms   | min ms   | matches |\n");
    std::printf("|---|---|---|---|---|\n");
    for (int n : sizes) ag::Run(n, repeats);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "match_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
