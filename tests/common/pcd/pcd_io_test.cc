#include "common/pcd/pcd_io.h"

#include <gtest/gtest.h>

#include <fstream>
#include <limits>
#include <random>
#include <stdexcept>

#include "common/core/error.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

using K = InputErrorKind;

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

PointCloud RandomCloud(int n, bool with_intensity, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coord(-80.0f, 80.0f);
  std::uniform_real_distribution<float> exponent(-30.0f, 30.0f);
  PointCloud cloud;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3f p(coord(rng), coord(rng), coord(rng));
    if (i % 7 == 0) p.z() = std::pow(10.0f, exponent(rng));  // awkward magnitudes
    cloud.points.push_back(p);
    if (with_intensity)
      cloud.intensity.push_back(std::uniform_real_distribution<float>(0, 255)(rng));
  }
  cloud.points.push_back(Eigen::Vector3f(std::numeric_limits<float>::denorm_min(), -0.0f,
                                         std::numeric_limits<float>::max()));
  if (with_intensity) cloud.intensity.push_back(0.1f);
  return cloud;
}

// The InputError ReadScan throws for `path` (a test failure if none).
InputError ReadError(const std::string& path) {
  try {
    ReadScan(path);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "ReadScan(" << path << ") did not throw";
  return InputError(K::kBadValue, "", 0, "");
}

TEST(PcdIoTest, RoundTripIsExact) {
  test::TempDir dir;
  for (const bool binary : {true, false}) {
    for (const bool with_intensity : {true, false}) {
      SCOPED_TRACE(std::string(binary ? "binary" : "ascii") +
                   (with_intensity ? " with intensity" : " without intensity"));
      const PointCloud cloud = RandomCloud(500, with_intensity, 3);
      const std::string path = dir / "scan.pcd";
      WriteScan(path, cloud, binary);
      const PointCloud back = ReadScan(path);
      ASSERT_EQ(back.points.size(), cloud.points.size());
      for (size_t i = 0; i < cloud.points.size(); ++i) {
        EXPECT_EQ(back.points[i], cloud.points[i]) << i;
      }
      EXPECT_EQ(back.intensity, cloud.intensity);
    }
  }
}

TEST(PcdIoTest, EmptyScanRoundTrips) {
  test::TempDir dir;
  for (const bool binary : {true, false}) {
    WriteScan(dir / "empty.pcd", PointCloud{}, binary);
    const PointCloud back = ReadScan(dir / "empty.pcd");
    EXPECT_TRUE(back.points.empty());
    EXPECT_TRUE(back.intensity.empty());
  }
}

TEST(PcdIoTest, HandWrittenAsciiPcdReads) {
  test::TempDir dir;
  WriteBytes(dir / "xyzi.pcd",
             "# .PCD v0.7 - Point Cloud Data file format\n"
             "VERSION 0.7\n"
             "FIELDS x y z intensity\n"
             "SIZE 4 4 4 4\n"
             "TYPE F F F F\n"
             "COUNT 1 1 1 1\n"
             "WIDTH 3\n"
             "HEIGHT 1\n"
             "VIEWPOINT 0 0 0 1 0 0 0\n"
             "POINTS 3\n"
             "DATA ascii\n"
             "1.5 -2.25 3 10\n"
             "0.125 0 -7.5 255\n"
             "100 200 -300 0.5\n");
  PointCloud cloud = ReadScan(dir / "xyzi.pcd");
  ASSERT_EQ(cloud.points.size(), 3u);
  EXPECT_EQ(cloud.points[0], Eigen::Vector3f(1.5f, -2.25f, 3.0f));
  EXPECT_EQ(cloud.points[1], Eigen::Vector3f(0.125f, 0.0f, -7.5f));
  EXPECT_EQ(cloud.points[2], Eigen::Vector3f(100.0f, 200.0f, -300.0f));
  EXPECT_EQ(cloud.intensity, (std::vector<float>{10.0f, 255.0f, 0.5f}));

  // x y z only, organised 2 x 2, with an extra field the format ignores.
  WriteBytes(dir / "xyz.pcd",
             "VERSION .7\n"
             "FIELDS ring x y z\n"
             "SIZE 2 4 4 4\n"
             "TYPE U F F F\n"
             "COUNT 1 1 1 1\n"
             "WIDTH 2\n"
             "HEIGHT 2\n"
             "VIEWPOINT 0 0 0 1 0 0 0\n"
             "POINTS 4\n"
             "DATA ascii\n"
             "0 1 2 3\n"
             "0 4 5 6\n"
             "1 7 8 9\n"
             "1 10 11 12\n");
  cloud = ReadScan(dir / "xyz.pcd");
  ASSERT_EQ(cloud.points.size(), 4u);
  EXPECT_EQ(cloud.points[3], Eigen::Vector3f(10, 11, 12));
  EXPECT_TRUE(cloud.intensity.empty());
}

TEST(PcdIoTest, HandWrittenBinaryPcdReads) {
  test::TempDir dir;
  const float data[6] = {1.0f, 2.0f, 3.0f, -4.0f, 5.5f, 6.25f};
  std::string bytes =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n";
  bytes.append(reinterpret_cast<const char*>(data), sizeof(data));
  WriteBytes(dir / "b.pcd", bytes);
  const PointCloud cloud = ReadScan(dir / "b.pcd");
  ASSERT_EQ(cloud.points.size(), 2u);
  EXPECT_EQ(cloud.points[1], Eigen::Vector3f(-4.0f, 5.5f, 6.25f));
}

std::string AsciiHeader(const std::string& fields, const std::string& size, const std::string& type,
                        int points) {
  std::string count;
  for (size_t i = 0; i < fields.size(); ++i) {
    if (fields[i] == ' ') count += "1 ";
  }
  count += "1";
  return "VERSION 0.7\nFIELDS " + fields + "\nSIZE " + size + "\nTYPE " + type + "\nCOUNT " +
         count + "\nWIDTH " + std::to_string(points) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n" +
         "POINTS " + std::to_string(points) + "\nDATA ascii\n";
}

TEST(PcdIoTest, ErrorsNameTheFile) {
  test::TempDir dir;
  struct Case {
    std::string name;
    std::string text;
    K kind;
    int64_t line;
    std::string fragment;
  };
  const std::vector<Case> cases = {
      {"no_z.pcd", AsciiHeader("x y intensity", "4 4 4", "F F F", 1) + "1 2 3\n", K::kMissingField,
       0, "'z'"},
      {"double_x.pcd", AsciiHeader("x y z", "8 4 4", "F F F", 1) + "1 2 3\n", K::kBadValue, 0,
       "float64"},
      {"int_y.pcd", AsciiHeader("x y z", "4 4 4", "F I F", 1) + "1 2 3\n", K::kBadValue, 0, "'y'"},
      {"uint8_intensity.pcd", AsciiHeader("x y z intensity", "4 4 4 1", "F F F U", 1) + "1 2 3 4\n",
       K::kBadValue, 0, "'intensity' is 1 x uint8"},
      {"nan.pcd", AsciiHeader("x y z", "4 4 4", "F F F", 3) + "1 2 3\n4 5 6\n7 nan 9\n",
       K::kNonFinite, 13, "point 2"},
      {"inf_intensity.pcd",
       AsciiHeader("x y z intensity", "4 4 4 4", "F F F F", 2) + "1 2 3 4\n4 5 6 inf\n",
       K::kNonFinite, 12, "point 1"},
      {"garbage.pcd", "this is not a point cloud\n", K::kMalformedRow, 1, "PCD header"},
      {"empty_file.pcd", "", K::kMalformedRow, 0, "no FIELDS"},
      {"no_data_line.pcd", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\n",
       K::kMalformedRow, 0, "no DATA"},
      {"bad_number.pcd", AsciiHeader("x y z", "4 4 4", "F F F", 2) + "1 2 3\n4 x 6\n",
       K::kMalformedRow, 12, "'x' is not a number"},
      {"short_row.pcd", AsciiHeader("x y z", "4 4 4", "F F F", 2) + "1 2 3\n4 5\n",
       K::kMalformedRow, 12, "expected 3 values, got 2"},
      {"too_few_rows.pcd", AsciiHeader("x y z", "4 4 4", "F F F", 3) + "1 2 3\n4 5 6\n",
       K::kMalformedRow, 0, "PCL could not parse it"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    WriteBytes(dir / c.name, c.text);
    const InputError e = ReadError(dir / c.name);
    EXPECT_EQ(e.kind(), c.kind) << e.what();
    EXPECT_EQ(e.file(), dir / c.name);
    EXPECT_EQ(e.line(), c.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(dir / c.name), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(c.fragment), std::string::npos) << e.what();
  }
  const InputError missing = ReadError(dir / "absent.pcd");
  EXPECT_EQ(missing.kind(), K::kMissingFile);
  EXPECT_EQ(missing.file(), dir / "absent.pcd");
}

TEST(PcdIoTest, BrokenBinaryPcdIsRefused) {
  test::TempDir dir;
  const float data[6] = {1.0f, 2.0f, 3.0f, std::numeric_limits<float>::quiet_NaN(), 5.0f, 6.0f};
  std::string bytes =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n";
  bytes.append(reinterpret_cast<const char*>(data), sizeof(data));
  WriteBytes(dir / "nan.pcd", bytes);
  const InputError e = ReadError(dir / "nan.pcd");
  EXPECT_EQ(e.kind(), K::kNonFinite);
  EXPECT_EQ(e.line(), 0);  // no lines in binary data; the message names the point
  EXPECT_NE(std::string(e.what()).find("point 1"), std::string::npos) << e.what();

  // Binary data shorter than the header promises.
  WriteBytes(dir / "truncated.pcd", bytes.substr(0, bytes.size() - 4));
  const InputError truncated = ReadError(dir / "truncated.pcd");
  EXPECT_EQ(truncated.kind(), K::kMalformedRow) << truncated.what();
  EXPECT_EQ(truncated.file(), dir / "truncated.pcd");
}

TEST(PcdIoTest, WriterRefusesInconsistentOrNonFiniteClouds) {
  test::TempDir dir;
  PointCloud cloud;
  cloud.points = {Eigen::Vector3f(1, 2, 3), Eigen::Vector3f(4, 5, 6)};
  cloud.intensity = {1.0f};
  EXPECT_THROW(WriteScan(dir / "a.pcd", cloud), std::invalid_argument);
  cloud.intensity.clear();
  cloud.points[1].y() = std::numeric_limits<float>::infinity();
  EXPECT_THROW(WriteScan(dir / "a.pcd", cloud), std::invalid_argument);
  cloud.points[1].y() = 5;
  try {
    WriteScan(dir / "no_such_folder/a.pcd", cloud);
    ADD_FAILURE() << "wrote into a missing folder";
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), K::kMissingFile);
    EXPECT_EQ(e.file(), dir / "no_such_folder/a.pcd");
  }
}

}  // namespace
}  // namespace ag
