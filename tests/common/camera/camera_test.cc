#include "common/camera/camera.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <random>
#include <vector>

#include "common/core/error.h"

namespace ag {
namespace {

// EuRoC cam0-like radtan camera (mild barrel distortion, invertible over the
// whole image).
CameraParams Radtan(int num_coefficients) {
  CameraParams p;
  p.model = "pinhole";
  p.width = 752;
  p.height = 480;
  p.fx = 458.654;
  p.fy = 457.296;
  p.cx = 367.215;
  p.cy = 248.375;
  p.distortion = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  if (num_coefficients == 5) p.distortion.push_back(0.0102);
  return p;
}

// Equidistant camera whose image corners are at about 76 degrees off axis,
// so every pixel has a bearing in front of the camera.
CameraParams Fisheye() {
  CameraParams p;
  p.model = "equidistant";
  p.width = 640;
  p.height = 480;
  p.fx = 301.2;
  p.fy = 300.4;
  p.cx = 321.7;
  p.cy = 238.9;
  p.distortion = {-0.0079, 0.044, -0.041, 0.0076};
  return p;
}

cv::Matx33d CameraMatrix(const CameraParams& p) {
  return cv::Matx33d(p.fx, 0, p.cx, 0, p.fy, p.cy, 0, 0, 1);
}

// Random points in front of the camera with |x/z| <= max_lateral and
// |y/z| <= 0.8 max_lateral.
std::vector<Eigen::Vector3d> RandomPoints(int n, unsigned seed, double max_lateral = 1.6) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> depth(0.2, 30.0);
  std::uniform_real_distribution<double> lateral(-max_lateral, max_lateral);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const double z = depth(rng);
    points.emplace_back(lateral(rng) * z, lateral(rng) * z * 0.8, z);
  }
  return points;
}

std::vector<cv::Point3d> ToCv(const std::vector<Eigen::Vector3d>& points) {
  std::vector<cv::Point3d> out;
  out.reserve(points.size());
  for (const auto& p : points) out.emplace_back(p.x(), p.y(), p.z());
  return out;
}

// Every pixel of a regular grid over the whole image, corners included.
std::vector<Eigen::Vector2d> ImageGrid(const CameraParams& p, double step) {
  std::vector<Eigen::Vector2d> grid;
  for (double v = 0.0; v <= p.height - 1 + 1e-9; v += step) {
    for (double u = 0.0; u <= p.width - 1 + 1e-9; u += step) grid.emplace_back(u, v);
    grid.emplace_back(p.width - 1, v);
  }
  for (double u = 0.0; u <= p.width - 1 + 1e-9; u += step) grid.emplace_back(u, p.height - 1);
  grid.emplace_back(p.width - 1, p.height - 1);
  return grid;
}

void ExpectProjectMatchesOpenCv(const CameraParams& params) {
  const Camera camera(params);
  const std::vector<Eigen::Vector3d> points = RandomPoints(2000, 7);
  std::vector<cv::Point2d> expected;
  const cv::Vec3d zero(0, 0, 0);
  if (camera.is_fisheye()) {
    cv::fisheye::projectPoints(ToCv(points), expected, zero, zero, CameraMatrix(params),
                               params.distortion);
  } else {
    cv::projectPoints(ToCv(points), zero, zero, CameraMatrix(params), params.distortion, expected);
  }
  double max_error = 0.0;
  for (size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera.Project(points[i], &uv));
    max_error = std::max(max_error, (uv - Eigen::Vector2d(expected[i].x, expected[i].y)).norm());
    // Project is ProjectT<double>, bit for bit.
    Eigen::Vector2d uv_t;
    camera.ProjectT(points[i].data(), uv_t.data());
    EXPECT_EQ(uv, uv_t);
  }
  EXPECT_LT(max_error, 1e-9) << params.model << " with " << params.distortion.size()
                             << " coefficients";
  std::printf("%s/%zu: max |Project - OpenCV| = %.3g px\n", params.model.c_str(),
              params.distortion.size(), max_error);
}

void ExpectRoundTripOverImage(const CameraParams& params) {
  const Camera camera(params);
  double max_error = 0.0;
  for (const Eigen::Vector2d& uv : ImageGrid(params, 4.0)) {
    const Eigen::Vector3d bearing = camera.Unproject(uv);
    EXPECT_NEAR(bearing.norm(), 1.0, 1e-12);
    Eigen::Vector2d back;
    ASSERT_TRUE(camera.Project(bearing, &back)) << uv.transpose();
    max_error = std::max(max_error, (back - uv).norm());
    EXPECT_LT((back - uv).norm(), 1e-8) << "at pixel " << uv.transpose();
  }
  std::printf("%s/%zu: max |project(unproject(uv)) - uv| = %.3g px\n", params.model.c_str(),
              params.distortion.size(), max_error);
}

TEST(CameraTest, ProjectMatchesOpenCvRadtan4) { ExpectProjectMatchesOpenCv(Radtan(4)); }
TEST(CameraTest, ProjectMatchesOpenCvRadtan5) { ExpectProjectMatchesOpenCv(Radtan(5)); }
TEST(CameraTest, ProjectMatchesOpenCvEquidistant) { ExpectProjectMatchesOpenCv(Fisheye()); }

TEST(CameraTest, UndistortMatchesOpenCvRadtan) {
  for (int n : {4, 5}) {
    const CameraParams params = Radtan(n);
    const Camera camera(params);
    const std::vector<Eigen::Vector2d> grid = ImageGrid(params, 16.0);
    std::vector<cv::Point2d> distorted, expected;
    for (const auto& uv : grid) distorted.emplace_back(uv.x(), uv.y());
    // OpenCV's fixed-point iteration, run long enough to converge.
    cv::undistortPoints(
        distorted, expected, CameraMatrix(params), params.distortion, cv::noArray(), cv::noArray(),
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 2000, 1e-15));
    double max_error = 0.0;
    for (size_t i = 0; i < grid.size(); ++i) {
      const Eigen::Vector2d x = camera.UndistortToNormalized(grid[i]);
      max_error = std::max(max_error, (x - Eigen::Vector2d(expected[i].x, expected[i].y)).norm());
    }
    EXPECT_LT(max_error, 1e-9) << n << " coefficients";
    std::printf("pinhole/%d: max |UndistortToNormalized - cv::undistortPoints| = %.3g\n", n,
                max_error);
  }
}

TEST(CameraTest, UndistortMatchesOpenCvEquidistant) {
  const CameraParams params = Fisheye();
  const Camera camera(params);
  const std::vector<Eigen::Vector2d> grid = ImageGrid(params, 16.0);
  std::vector<cv::Point2d> distorted, expected;
  for (const auto& uv : grid) distorted.emplace_back(uv.x(), uv.y());
  cv::fisheye::undistortPoints(
      distorted, expected, CameraMatrix(params), params.distortion, cv::noArray(), cv::noArray(),
      cv::TermCriteria(cv::TermCriteria::MAX_ITER | cv::TermCriteria::EPS, 100, 1e-15));
  double max_error = 0.0;
  for (size_t i = 0; i < grid.size(); ++i) {
    const Eigen::Vector2d x = camera.UndistortToNormalized(grid[i]);
    max_error = std::max(max_error, (x - Eigen::Vector2d(expected[i].x, expected[i].y)).norm());
  }
  EXPECT_LT(max_error, 1e-9);
  std::printf("equidistant: max |UndistortToNormalized - cv::fisheye::undistortPoints| = %.3g\n",
              max_error);
}

TEST(CameraTest, ProjectOfUnprojectIsIdentityOverImageRadtan4) {
  ExpectRoundTripOverImage(Radtan(4));
}
TEST(CameraTest, ProjectOfUnprojectIsIdentityOverImageRadtan5) {
  ExpectRoundTripOverImage(Radtan(5));
}
TEST(CameraTest, ProjectOfUnprojectIsIdentityOverImageEquidistant) {
  ExpectRoundTripOverImage(Fisheye());
}

TEST(CameraTest, UnprojectOfProjectRecoversBearing) {
  for (const CameraParams& params : {Radtan(5), Fisheye()}) {
    const Camera camera(params);
    // Within |x/z| < 0.8 the radtan polynomial is monotonic; farther out it
    // folds back into the image and the bearing is not unique.
    int checked = 0;
    for (const Eigen::Vector3d& p_c : RandomPoints(500, 11, 0.8)) {
      Eigen::Vector2d uv;
      ASSERT_TRUE(camera.Project(p_c, &uv));
      if (!camera.InImage(uv)) continue;
      EXPECT_LT((camera.Unproject(uv) - p_c.normalized()).norm(), 1e-10) << params.model;
      ++checked;
    }
    EXPECT_GT(checked, 300);
  }
}

TEST(CameraTest, NoDistortionIsPlainPinhole) {
  for (const char* model : {"pinhole", "equidistant"}) {
    CameraParams params = Radtan(4);
    params.model = model;
    params.distortion.clear();
    const Camera camera(params);
    const Eigen::Vector3d p_c(0.3, -0.2, 2.0);
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera.Project(p_c, &uv));
    if (camera.is_fisheye()) {
      // Equidistant without distortion: pixel radius = f * theta.
      const double theta = std::atan(std::hypot(0.15, 0.1));
      const Eigen::Vector2d expected(params.fx * 0.15 * theta / std::hypot(0.15, 0.1) + params.cx,
                                     params.fy * -0.1 * theta / std::hypot(0.15, 0.1) + params.cy);
      EXPECT_LT((uv - expected).norm(), 1e-12);
    } else {
      EXPECT_LT(
          (uv - Eigen::Vector2d(params.fx * 0.15 + params.cx, params.fy * -0.1 + params.cy)).norm(),
          1e-12);
      const Eigen::Vector2d pixel(100.5, 33.25);
      EXPECT_LT((camera.UndistortToNormalized(pixel) -
                 Eigen::Vector2d((pixel.x() - params.cx) / params.fx,
                                 (pixel.y() - params.cy) / params.fy))
                    .norm(),
                1e-15);
      EXPECT_LT((camera.UndistortPixel(pixel) - pixel).norm(), 1e-12);
    }
    // The optical axis maps to the principal point.
    ASSERT_TRUE(camera.Project(Eigen::Vector3d(0, 0, 5), &uv));
    EXPECT_EQ(uv, Eigen::Vector2d(params.cx, params.cy));
    EXPECT_LT((camera.Unproject(uv) - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  }
}

TEST(CameraTest, PointsBehindOrOnTheCameraAreRefused) {
  for (const CameraParams& params : {Radtan(4), Fisheye()}) {
    const Camera camera(params);
    Eigen::Vector2d uv(-7.0, -7.0);
    EXPECT_FALSE(camera.Project(Eigen::Vector3d(0.1, 0.2, -1.0), &uv));
    EXPECT_FALSE(camera.Project(Eigen::Vector3d(0.1, 0.2, 0.0), &uv));
    EXPECT_FALSE(camera.Project(Eigen::Vector3d(0.0, 0.0, -5.0), &uv));
    EXPECT_FALSE(camera.Project(Eigen::Vector3d(1.0, 0.0, 1e-9), &uv));
    EXPECT_FALSE(camera.Project(Eigen::Vector3d(NAN, 0.0, 1.0), &uv));
    EXPECT_FALSE(camera.Project(Eigen::Vector3d(0.0, INFINITY, 1.0), &uv));
    EXPECT_EQ(uv, Eigen::Vector2d(-7.0, -7.0)) << "output untouched when refused";
    EXPECT_TRUE(camera.Project(Eigen::Vector3d(0.1, 0.2, 1.0), &uv));
  }
}

TEST(CameraTest, InImageUsesBorder) {
  const Camera camera(Radtan(4));
  EXPECT_TRUE(camera.InImage(Eigen::Vector2d(0, 0)));
  EXPECT_TRUE(camera.InImage(Eigen::Vector2d(751, 479)));
  EXPECT_FALSE(camera.InImage(Eigen::Vector2d(751.01, 479)));
  EXPECT_FALSE(camera.InImage(Eigen::Vector2d(-0.01, 10)));
  EXPECT_FALSE(camera.InImage(Eigen::Vector2d(5, 10), 8.0));
  EXPECT_TRUE(camera.InImage(Eigen::Vector2d(8, 10), 8.0));
  EXPECT_FALSE(camera.InImage(Eigen::Vector2d(NAN, 10)));
}

// Constructs a camera from `params` and returns the field named by the
// OptionError it threw (empty and a test failure if it did not throw).
std::string InvalidField(const CameraParams& params, std::string* message) {
  try {
    Camera camera(params);
  } catch (const OptionError& e) {
    *message = e.what();
    return e.field();
  }
  ADD_FAILURE() << "Camera accepted invalid parameters";
  return "";
}

TEST(CameraTest, InvalidParametersThrowNamingTheField) {
  struct Case {
    CameraParams params;
    std::string field;
    std::string fragment;
  };
  std::vector<Case> cases;
  auto add = [&](const std::string& field, const std::string& fragment, auto mutate) {
    CameraParams p = Radtan(4);
    mutate(p);
    cases.push_back({p, field, fragment});
  };
  add("model", "radtan", [](CameraParams& p) { p.model = "radtan"; });
  add("width", "0", [](CameraParams& p) { p.width = 0; });
  add("height", "-3", [](CameraParams& p) { p.height = -3; });
  add("intrinsics", "fx", [](CameraParams& p) { p.fx = 0.0; });
  add("intrinsics", "fy", [](CameraParams& p) { p.fy = -400.0; });
  add("intrinsics", "finite", [](CameraParams& p) { p.cx = NAN; });
  add("distortion", "got 3", [](CameraParams& p) { p.distortion.resize(3); });
  add("distortion", "got 6", [](CameraParams& p) { p.distortion.resize(6); });
  add("distortion", "equidistant needs 4 values, got 5", [](CameraParams& p) {
    p.model = "equidistant";
    p.distortion.resize(5);
  });
  add("distortion", "not finite", [](CameraParams& p) { p.distortion[1] = INFINITY; });
  for (const Case& c : cases) {
    std::string message;
    EXPECT_EQ(InvalidField(c.params, &message), c.field) << message;
    EXPECT_NE(message.find(c.fragment), std::string::npos) << message;
  }
}

TEST(CameraTest, ValidDistortionCountsAreAccepted) {
  CameraParams p = Radtan(4);
  for (size_t n : {0u, 4u, 5u}) {
    p.distortion.assign(n, 0.01);
    EXPECT_NO_THROW(Camera{p}) << n;
  }
  p.model = "equidistant";
  for (size_t n : {0u, 4u}) {
    p.distortion.assign(n, 0.01);
    EXPECT_NO_THROW(Camera{p}) << n;
  }
}

}  // namespace
}  // namespace ag
