#include "tools/sim/world.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "tests/support/test_support.h"
#include "tools/sim/random.h"

namespace ag {
namespace {

using Eigen::Vector3d;

SimWorld OneOfEach() {
  SimWorld world(3);
  SimObject box;
  box.shape = SimObject::Shape::kBox;
  box.center = Vector3d(10, 0, 1.5);
  box.half = Vector3d(1.0, 2.0, 1.5);
  box.yaw = 0.0;
  world.AddObject(box, MaterialKind::kBrick, MaterialKind::kRoof);
  SimObject pole;
  pole.shape = SimObject::Shape::kCylinder;
  pole.center = Vector3d(0, 10, 2.0);
  pole.half = Vector3d(0.5, 0.5, 2.0);
  world.AddObject(pole, MaterialKind::kMetal, MaterialKind::kMetal);
  SimObject ball;
  ball.shape = SimObject::Shape::kSphere;
  ball.center = Vector3d(-10, 0, 3.0);
  ball.half = Vector3d::Constant(2.0);
  world.AddObject(ball, MaterialKind::kFoliage, MaterialKind::kFoliage);
  world.BuildIndex();
  return world;
}

TEST(SimWorld, RaysHitEachShapeWhereGeometrySays) {
  const SimWorld world = OneOfEach();
  const Vector3d o(0, 0, 1.0);
  RayHit hit;
  // Box face x = 9.
  ASSERT_TRUE(world.Cast(o, Vector3d::UnitX(), 1e3, &hit));
  EXPECT_NEAR(hit.t, 9.0, 1e-12);
  EXPECT_EQ(hit.object, 0);
  EXPECT_NEAR(hit.n.x(), -1.0, 1e-12);
  // Cylinder side y = 9.5.
  ASSERT_TRUE(world.Cast(o, Vector3d::UnitY(), 1e3, &hit));
  EXPECT_NEAR(hit.t, 9.5, 1e-12);
  EXPECT_EQ(hit.object, 1);
  // Sphere: centre (-10, 0, 3), radius 2, along the ray to its centre.
  const Vector3d to_ball = (Vector3d(-10, 0, 3) - o).normalized();
  ASSERT_TRUE(world.Cast(o, to_ball, 1e3, &hit));
  EXPECT_NEAR(hit.t, (Vector3d(-10, 0, 3) - o).norm() - 2.0, 1e-9);
  EXPECT_EQ(hit.object, 2);
  // Ground plane.
  const Vector3d down = Vector3d(1, 1, -1).normalized();
  ASSERT_TRUE(world.Cast(o, down, 1e3, &hit));
  EXPECT_EQ(hit.object, -1);
  EXPECT_NEAR(hit.t, std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(hit.p.z(), 0.0, 1e-15);
  // Sky.
  EXPECT_FALSE(world.Cast(o, Vector3d(0, -1, 1).normalized(), 1e3, &hit));
}

TEST(SimWorld, GridTraversalAgreesWithBruteForce) {
  WorldOptions options;
  options.size_x_m = 40;
  options.size_y_m = 40;
  const SimWorld world = SimWorld::Generate(options, 11, {});
  ASSERT_GT(world.objects().size(), 50u);
  // The same objects, cast without the grid: one world per object, keeping
  // the nearest hit.
  std::vector<SimWorld> singles;
  for (const SimObject& object : world.objects()) {
    singles.emplace_back(3);
    singles.back().AddObject(object, MaterialKind::kConcrete, MaterialKind::kConcrete);
    singles.back().BuildIndex();
  }
  SimRandom rng(5);
  int hits = 0;
  for (int i = 0; i < 3000; ++i) {
    const Vector3d o(rng.Uniform(-25, 25), rng.Uniform(-25, 25), rng.Uniform(0.2, 15.0));
    Vector3d d(rng.Gaussian(), rng.Gaussian(), rng.Gaussian() - 0.3);
    d.normalize();
    RayHit hit;
    const bool found = world.Cast(o, d, 200.0, &hit);
    double best = d.z() < 0 ? -o.z() / d.z() : std::numeric_limits<double>::infinity();
    if (best > 200.0) best = std::numeric_limits<double>::infinity();
    bool inside_any = false;
    for (size_t k = 0; k < world.objects().size(); ++k) {
      RayHit h;
      if (singles[k].Cast(o, d, best, &h) && h.object == 0) best = std::min(best, h.t);
      // Rays starting inside a solid are ambiguous (they never happen in a
      // scenario: paths are kept clear); skip them.
      const SimObject& ob = world.objects()[k];
      if ((o - ob.center).cwiseAbs().maxCoeff() < ob.half.maxCoeff()) inside_any = true;
    }
    if (inside_any) continue;
    ASSERT_EQ(found, std::isfinite(best)) << "ray " << i;
    if (found) {
      EXPECT_NEAR(hit.t, best, 1e-9) << "ray " << i;
      ++hits;
    }
  }
  EXPECT_GT(hits, 1000);
}

// Irradiance skips the shadow ray where no object can block the sun; that
// shortcut must never change a shadow.
TEST(SimWorld, SunShortcutAgreesWithShadowRays) {
  WorldOptions options;
  options.size_x_m = 40;
  options.size_y_m = 40;
  const SimWorld world = SimWorld::Generate(options, 11, {});
  SimRandom rng(6);
  int lit = 0, shadowed = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vector3d o(rng.Uniform(-40, 40), rng.Uniform(-40, 40), rng.Uniform(0.3, 20.0));
    Vector3d d(rng.Gaussian(), rng.Gaussian(), rng.Gaussian() - 0.5);
    d.normalize();
    RayHit hit;
    if (!world.Cast(o, d, 500.0, &hit)) continue;
    bool shadow = false;
    world.Irradiance(hit, &shadow);
    const bool expected = hit.n.dot(world.sun_direction()) <= 0.0 ||
                          world.Occluded(hit.p + 1e-6 * hit.n, world.sun_direction(), 1e4, 1e-6);
    ASSERT_EQ(shadow, expected) << "ray " << i;
    ++(shadow ? shadowed : lit);
  }
  EXPECT_GT(lit, 2000);
  EXPECT_GT(shadowed, 2000);
}

TEST(SimWorld, GenerationKeepsPathsClearAndIsDeterministic) {
  WorldOptions options;
  KeepOutPath path;
  for (int i = 0; i < 100; ++i) path.points.emplace_back(-20.0 + 0.4 * i, 3.0);
  path.radius_m = 2.0;
  const SimWorld a = SimWorld::Generate(options, 42, {path});
  const SimWorld b = SimWorld::Generate(options, 42, {path});
  const SimWorld c = SimWorld::Generate(options, 43, {path});
  ASSERT_EQ(a.objects().size(), b.objects().size());
  for (size_t k = 0; k < a.objects().size(); ++k) {
    EXPECT_EQ(a.objects()[k].center, b.objects()[k].center);
    EXPECT_EQ(a.objects()[k].half, b.objects()[k].half);
  }
  EXPECT_NE(a.objects().front().center, c.objects().front().center);
  // No ray along the path at camera height hits anything.
  RayHit hit;
  for (double x = -19.0; x < 19.0; x += 0.5) {
    EXPECT_FALSE(a.Cast(Vector3d(x, 3.0, 0.5), Vector3d::UnitX(), 0.5, &hit)) << "x " << x;
  }
}

TEST(SimTexture, SamePointLooksTheSameAndFarViewsAverage) {
  const SurfaceTexture ground(MaterialKind::kGround, 7);
  const Eigen::Vector2d p(3.2, -1.7);
  // Same point, same footprint: same albedo (a pure function of the point).
  EXPECT_EQ(ground.Albedo(p, 0.003), ground.Albedo(p, 0.003));
  // Close views have detail: neighbouring samples 2 cm apart differ.
  SimRandom rng(1);
  double close_var = 0.0, far_var = 0.0;
  const int n = 400;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d q(rng.Uniform(0, 0.5), rng.Uniform(0, 0.5));
    const double a = ground.Albedo(q, 0.003).mean(),
                 b = ground.Albedo(q + Eigen::Vector2d(0.02, 0), 0.003).mean();
    const double fa = ground.Albedo(q, 0.5).mean(),
                 fb = ground.Albedo(q + Eigen::Vector2d(0.02, 0), 0.5).mean();
    close_var += (a - b) * (a - b);
    far_var += (fa - fb) * (fa - fb);
  }
  // Prefiltering: at a 0.5 m footprint the 2 cm-scale differences vanish.
  EXPECT_GT(close_var / n, 1e-4);
  EXPECT_LT(far_var, 0.05 * close_var);
}

TEST(SimTexture, ImagesFromAFolderReplaceTheProceduralAlbedo) {
  test::TempDir dir;
  // A reddish and a bluish image (BGR), with a little structure.
  cv::Mat red(64, 64, CV_8UC3, cv::Scalar(40, 40, 200)),
      blue(64, 64, CV_8UC3, cv::Scalar(200, 60, 40));
  for (int r = 0; r < 64; ++r) {
    for (int c = 0; c < 64; c += 8) {
      red.at<cv::Vec3b>(r, c) = cv::Vec3b(20, 20, 120);
      blue.at<cv::Vec3b>(c, r) = cv::Vec3b(120, 30, 20);
    }
  }
  ASSERT_TRUE(cv::imwrite(dir / "a_red.png", red));
  ASSERT_TRUE(cv::imwrite(dir / "b_blue.png", blue));
  const TextureImages images = TextureImages::LoadFolder(dir.path(), 0.01);
  ASSERT_EQ(images.size(), 2u);
  // Every surface uses one of the images: red or blue dominates everywhere
  // (decals aside), never the procedural greys and greens.
  int coloured = 0;
  SimRandom rng(2);
  for (uint64_t s = 0; s < 20; ++s) {
    const SurfaceTexture texture(MaterialKind::kConcrete, s);
    const Eigen::Vector3f c = texture.Albedo(Eigen::Vector2d(rng.Uniform(0, 5), rng.Uniform(0, 5)),
                                             0.002, Eigen::Vector2d::Zero(), 1, &images);
    if (c.x() > 3.0f * c.z() || c.z() > 3.0f * c.x()) ++coloured;
  }
  EXPECT_GE(coloured, 16);
  test::TempDir empty;
  EXPECT_THROW(TextureImages::LoadFolder(empty.path(), 0.01), InputError);
  EXPECT_THROW(TextureImages::LoadFolder(empty / "missing", 0.01), InputError);
}

}  // namespace
}  // namespace ag
