#pragma once

// Helpers shared by the dataset tests: a small dataset written by hand (not
// by DatasetWriter, so the reader is checked against the spec's text, as
// data made elsewhere would be), and an assertion on the InputError thrown.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "common/core/error.h"
#include "common/dataset/dataset.h"

namespace ag::test {

inline void WriteText(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// `text` with the one occurrence of `from` replaced (fails the test if
/// `from` does not occur exactly once).
inline std::string ReplaceOnce(const std::string& text, const std::string& from,
                               const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "'" << from << "' not in:\n" << text;
  if (at == std::string::npos) return text;
  EXPECT_EQ(text.find(from, at + 1), std::string::npos) << "'" << from << "' occurs twice";
  return text.substr(0, at) + to + text.substr(at + from.size());
}

/// Runs `read` and checks the InputError it throws: kind, file, line, that
/// the message names "file:line:" (or the file alone for line 0), and that
/// it contains `fragment`.
inline void ExpectInputError(const std::function<void()>& read, InputErrorKind kind,
                             const std::string& file, int64_t line,
                             const std::string& fragment = "") {
  try {
    read();
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.kind(), kind) << "got " << ToString(e.kind()) << ": " << what;
    EXPECT_EQ(e.file(), file) << what;
    EXPECT_EQ(e.line(), line) << what;
    const std::string where = line > 0 ? file + ":" + std::to_string(line) + ": " : file + ": ";
    EXPECT_EQ(what.rfind(where, 0), 0u)
        << "message does not start with '" << where << "': " << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << "'" << fragment << "' not in: " << what;
    return;
  }
  ADD_FAILURE() << "no InputError thrown (expected " << ToString(kind) << " in " << file << ":"
                << line << ")";
}

// Line numbers of these texts are used by the tests: keep them stable.
inline constexpr const char* kDatasetYaml =
    "format_version: 1\n"
    "name: fixture\n"
    "description: a dataset written by hand\n";

inline constexpr const char* kGroundCalibration =
    "camera:\n"                                                                          // 1
    "  model: pinhole\n"                                                                 // 2
    "  width: 64\n"                                                                      // 3
    "  height: 48\n"                                                                     // 4
    "  intrinsics: [50.0, 51.0, 32.0, 24.0]\n"                                           // 5
    "  distortion: [-0.1, 0.01, 0.001, -0.002]\n"                                        // 6
    "  T_body_camera: [[0, 0, 1, 0.1], [-1, 0, 0, 0], [0, -1, 0, 0.2], [0, 0, 0, 1]]\n"  // 7
    "  time_offset_s: 0.004\n"                                                           // 8
    "lidar:\n"                                                                           // 9
    "  T_body_lidar:\n"                                                                  // 10
    "    - [1, 0, 0, 0]\n"                                                               // 11
    "    - [0, 1, 0, 0]\n"                                                               // 12
    "    - [0, 0, 1, 0.3]\n"                                                             // 13
    "    - [0, 0, 0, 1]\n"                                                               // 14
    "  time_offset_s: -0.01\n";                                                          // 15

inline constexpr const char* kAirCalibration =
    "# a fisheye camera\n"
    "camera:\n"
    "  model: equidistant\n"
    "  width: 64\n"
    "  height: 48\n"
    "  intrinsics: [30, 30, 32, 24]\n"
    "  distortion: [0.01, -0.002, 0.0003, 0]\n"
    "  T_body_camera: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n";

inline constexpr const char* kImagesCsv =
    "#timestamp [ns],filename\n"    // 1
    "1000000000,1000000000.png\n"   // 2
    "1100000000,1100000000.png\n";  // 3

inline constexpr const char* kScansCsv =
    "#timestamp [ns],filename\n"
    "1000000000,1000000000.pcd\n"
    "1100000000,1100000000.pcd\n";

inline constexpr const char* kOdometryTum =
    "# timestamp tx ty tz qx qy qz qw\n"                         // 1
    "1.000000000 0 0 0 0 0 0 1\n"                                // 2
    "1.100000000 0.1 0 0 0 0 0 1\n"                              // 3
    "1.200000000 0.2 0 0 0 0 0.0499791692707 0.998750260395\n";  // 4

inline constexpr const char* kGroundTruthYaml =
    "T_wa_wg:\n"                                                              // 1
    "  uav1: [[0, -1, 0, 5], [1, 0, 0, -2], [0, 0, 1, 0.5], [0, 0, 0, 1]]\n"  // 2
    "true_calibration:\n"                                                     // 3
    "  ground: {T_body_camera: [[0, 0, 1, 0.1], [-1, 0, 0, 0], [0, -1, 0, 0.2], [0, 0, 0, 1]],"
    " camera_time_offset_s: 0.005}\n"  // 4
    "  air: {uav1: {T_body_camera: [[1, 0, 0, 0.01], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],"
    " camera_time_offset_s: -0.002}}\n";  // 5

/// A tiny but complete dataset in `dir`: ground agent (camera + lidar) and
/// one air agent "uav1", groundtruth.yaml, no groundtruth.tum.
inline void WriteFixtureDataset(const std::string& dir) {
  WriteText(dir + "/dataset.yaml", kDatasetYaml);
  const cv::Mat image(48, 64, CV_8UC1, cv::Scalar(7));
  for (const std::string agent : {"ground", "air/uav1"}) {
    const std::string a = dir + "/" + agent;
    WriteText(a + "/calibration.yaml", agent == "ground" ? kGroundCalibration : kAirCalibration);
    WriteText(a + "/images.csv", kImagesCsv);
    std::filesystem::create_directories(a + "/images");
    cv::imwrite(a + "/images/1000000000.png", image);
    cv::imwrite(a + "/images/1100000000.png", image);
    WriteText(a + "/odometry.tum", kOdometryTum);
  }
  WriteText(dir + "/ground/scans.csv", kScansCsv);
  // The dataset reader only checks that scans exist; ag::pcd reads them.
  WriteText(dir + "/ground/scans/1000000000.pcd", "not read here\n");
  WriteText(dir + "/ground/scans/1100000000.pcd", "not read here\n");
  WriteText(dir + "/groundtruth.yaml", kGroundTruthYaml);
}

}  // namespace ag::test
