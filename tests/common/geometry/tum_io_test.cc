#include "common/geometry/tum_io.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "common/core/error.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

void WriteText(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// Runs ReadTum and returns the error it threw (fails the test if none).
InputError ReadError(const std::string& path) {
  try {
    ReadTum(path);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "ReadTum(" << path << ") did not throw";
  return InputError(InputErrorKind::kBadValue, "", 0, "");
}

TEST(TumIoTest, DecimalSecondsAreExact) {
  int64_t t = 0;
  ASSERT_TRUE(ParseDecimalSecondsNs("1700000000.123456789", &t));
  EXPECT_EQ(t, 1700000000123456789LL);
  ASSERT_TRUE(ParseDecimalSecondsNs("12.5", &t));
  EXPECT_EQ(t, 12500000000LL);
  ASSERT_TRUE(ParseDecimalSecondsNs("7", &t));
  EXPECT_EQ(t, 7000000000LL);
  EXPECT_FALSE(ParseDecimalSecondsNs("1.1234567891", &t));
  EXPECT_FALSE(ParseDecimalSecondsNs("abc", &t));
  EXPECT_EQ(FormatDecimalSecondsNs(1700000000000000001LL), "1700000000.000000001");
  EXPECT_EQ(FormatDecimalSecondsNs(-1500000000LL), "-1.500000000");
}

TEST(TumIoTest, WriteThenReadIsIdentical) {
  test::TempDir dir;
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 10.0);
  std::vector<StampedPose> poses;
  for (int i = 0; i < 100; ++i) {
    StampedPose p;
    p.t_ns = 1700000000000000000LL + i * 10000001LL;
    p.T.linear() =
        Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized().toRotationMatrix();
    p.T.translation() = Eigen::Vector3d(n(rng), n(rng), n(rng));
    poses.push_back(p);
  }
  WriteTum(dir / "traj.tum", poses);
  const auto back = ReadTum(dir / "traj.tum");
  ASSERT_EQ(back.size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(back[i].t_ns, poses[i].t_ns);
    EXPECT_TRUE(back[i].T.matrix().isApprox(poses[i].T.matrix(), 1e-15));
  }
}

TEST(TumIoTest, CommentsAndBlankLinesAreSkipped) {
  test::TempDir dir;
  WriteText(dir / "t.tum", "# header\n\n1.0 0 0 0 0 0 0 1\n   \n# x\n2.0 1 2 3 0 0 0 1\n");
  const auto poses = ReadTum(dir / "t.tum");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[1].t_ns, 2000000000LL);
  EXPECT_EQ(poses[1].T.translation(), Eigen::Vector3d(1, 2, 3));
}

TEST(TumIoTest, ErrorsNameFileLineAndProblem) {
  test::TempDir dir;
  struct Case {
    const char* text;
    InputErrorKind kind;
    int64_t line;
  };
  const Case cases[] = {
      {"1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", InputErrorKind::kMalformedRow, 2},
      {"1.0 0 0 x 0 0 0 1\n", InputErrorKind::kMalformedRow, 1},
      {"# c\n1.0 0 nan 0 0 0 0 1\n", InputErrorKind::kNonFinite, 2},
      {"1.0 0 0 0 0 0 0 2\n", InputErrorKind::kNotRotation, 1},
      {"2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n", InputErrorKind::kUnsorted, 2},
      {"1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n", InputErrorKind::kUnsorted, 2},
  };
  for (const Case& c : cases) {
    WriteText(dir / "bad.tum", c.text);
    const InputError e = ReadError(dir / "bad.tum");
    EXPECT_EQ(e.kind(), c.kind) << c.text << " -> " << e.what();
    EXPECT_EQ(e.line(), c.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(dir / "bad.tum"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(":" + std::to_string(c.line) + ":"), std::string::npos);
  }
  const InputError missing = ReadError(dir / "absent.tum");
  EXPECT_EQ(missing.kind(), InputErrorKind::kMissingFile);
}

}  // namespace
}  // namespace ag
