// match_bench: time of one air-ground descriptor matching (mutual nearest
// neighbour + ratio test) per backend and keypoint count, on the calling
// thread, as the estimator runs it; then a few rows against a whole
// keyframe, as stage 1 matches one keyframe's tracks against another.
// Prints tables; nothing is asserted (tests check that every backend
// returns the same matches).
//
//   match_bench [--sizes 256,512,1024] [--repeats 20] [--rows 25,50,96,200,400]
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

// `rows` UGV descriptors for the UAV set `other` (see Data above).
cv::Mat NoisyCopy(const cv::Mat& other, int rows, std::mt19937* rng) {
  cv::Mat out = RandomUnitRows(rows, rng);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (int r = 0; r < rows * 6 / 10; ++r) {
    cv::Mat row = out.row(r);
    other.row((r * 7) % other.rows).copyTo(row);
    for (int c = 0; c < 64; ++c) row.at<float>(c) += noise(*rng);
    cv::normalize(row, row);
  }
  return out;
}

// One line per backend: median and minimum thread CPU time of matching
// `ugv` against `air`, and the number of matches.
void TimeBackends(const cv::Mat& ugv, const cv::Mat& air, int repeats) {
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
    std::printf("| %5d x %-5d | %-7s | %8.2f | %8.2f | %8.2f | %7zu |\n", ugv.rows, air.rows,
                backend.c_str(), ms[ms.size() / 2], ms.front(), 1e3 * ms[ms.size() / 2] / ugv.rows,
                matches);
  }
}

}  // namespace
}  // namespace ag

int main(int argc, char** argv) {
  try {
    CLI::App app("Descriptor matching benchmark: time per backend and keypoint count");
    std::vector<int> sizes = {256, 512, 1024};
    int repeats = 20;
    app.add_option("--sizes", sizes, "keypoints on each side")
        ->delimiter(',')
        ->check(CLI::PositiveNumber);
    app.add_option("--repeats", repeats, "matchings per size and backend")
        ->check(CLI::PositiveNumber);
    std::vector<int> rows = {25, 50, 96, 200, 400};
    app.add_option("--rows", rows, "tracks matched against a 1024-keypoint keyframe")
        ->delimiter(',')
        ->check(CLI::PositiveNumber);
    CLI11_PARSE(app, argc, argv);
    std::printf("match_bench: 64-D float descriptors, one thread, CPU time of this thread\n");
    std::printf("| UGV x UAV     | backend | med ms   | min ms   | us/row   | matches |\n");
    std::printf("|---|---|---|---|---|---|\n");
    for (int n : sizes) {
      std::mt19937 rng(7);
      const cv::Mat air = ag::RandomUnitRows(n, &rng);
      ag::TimeBackends(ag::NoisyCopy(air, n, &rng), air, repeats);
    }
    std::printf("\nOne keyframe's stage-1 tracks against another keyframe (1024 keypoints)\n");
    std::printf("| tracks x kps  | backend | med ms   | min ms   | us/row   | matches |\n");
    std::printf("|---|---|---|---|---|---|\n");
    std::mt19937 rng(7);
    const cv::Mat keyframe = ag::RandomUnitRows(1024, &rng);
    for (int n : rows) ag::TimeBackends(ag::NoisyCopy(keyframe, n, &rng), keyframe, repeats);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "match_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
