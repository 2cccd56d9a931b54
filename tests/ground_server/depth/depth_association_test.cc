#include "ground_server/depth/depth_association.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "tests/ground_server/depth/synthetic_scene.h"
#include "tests/support/option_error.h"

namespace ag {
namespace {

using test::Scene;

CameraParams Pinhole(std::vector<double> distortion = {}) {
  CameraParams p;
  p.model = "pinhole";
  p.width = 640;
  p.height = 480;
  p.fx = 500;
  p.fy = 500;
  p.cx = 319.5;
  p.cy = 239.5;
  p.distortion = std::move(distortion);
  return p;
}

CameraParams Fisheye() {
  CameraParams p;
  p.model = "equidistant";
  p.width = 640;
  p.height = 480;
  p.fx = 280;
  p.fy = 280;
  p.cx = 320;
  p.cy = 240;
  p.distortion = {0.02, -0.01, 0.003, -0.001};
  return p;
}

// Camera at `position` looking along world +x, pitched down by `pitch` rad.
Pose ForwardCamera(const Eigen::Vector3d& position, double pitch) {
  Eigen::Matrix3d base;  // columns: camera x, y, z axes in the world
  base << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()).toRotationMatrix() * base;
  T.translation() = position;
  return T;
}

// Floor, back wall and a box in front of it.
Scene StreetScene() {
  Scene scene;
  scene.AddRect(2, 0.0, Eigen::Vector2d(-9, 0), Eigen::Vector2d(9, 12));     // floor z = 0 (y, x)
  scene.AddRect(0, 12.0, Eigen::Vector2d(-9, 0), Eigen::Vector2d(9, 3));     // wall x = 12 (y, z)
  scene.AddBox(Eigen::Vector3d(5, -1.5, 0), Eigen::Vector3d(6, -0.3, 1.4));  // box
  return scene;
}

// Recovered keypoint depths against exact ray casting. Error model: the
// accepted map point q lies on the true surface, within a perpendicular
// distance delta <= pixel_threshold * range / f of the ray (the reprojection
// test; off-axis pixels only make delta smaller). The returned foot differs
// from the true hit only along the ray, by (q - x_true).b, which for q in a
// plane meeting the ray at angle alpha is at most delta * cot(alpha). The
// bound uses 1.5 * delta * cot(alpha) + 5 mm (float storage of the points).
TEST(DepthAssociationTest, RecoversKnownGeometryWithinTheReprojectionBound) {
  const Scene scene = StreetScene();
  std::mt19937 rng(11);
  VoxelGrid::Options map_options;
  map_options.max_points_per_voxel = 30;
  VoxelGrid map(map_options);
  map.Insert(scene.Sample(2500.0, &rng), Eigen::Vector3d(0, 0, 1.2));

  const Camera camera(Pinhole());
  DepthAssociator::Options options;
  options.pixel_threshold_px = 3.0;
  const DepthAssociator associator(camera, options);
  const Pose T_wg_c = ForwardCamera(Eigen::Vector3d(0, 0, 1.2), 0.14);

  std::vector<Eigen::Vector2f> keypoints;
  for (int v = 4; v < 480; v += 8) {
    for (int u = 4; u < 640; u += 8) keypoints.emplace_back(u + 0.25f, v + 0.5f);
  }
  const DepthAssociationResult result = associator.Associate(map, T_wg_c, keypoints);
  ASSERT_EQ(result.keypoints.size(), keypoints.size());

  const Eigen::Vector3d o = T_wg_c.translation();
  auto cast = [&](const Eigen::Vector2d& uv, double* t, int* rect) {
    const Eigen::Vector3d d = T_wg_c.linear() * camera.Unproject(uv);
    return scene.Cast(o, d, options.min_range_m, options.max_range_m, t, rect);
  };
  int surface = 0, surface_valid = 0, surface_far = 0, surface_far_valid = 0;
  int within = 0, sky = 0, sky_valid = 0;
  std::vector<double> errors;
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const Eigen::Vector2d uv = keypoints[i].cast<double>();
    const KeypointDepth& got = result.keypoints[i];
    double t = 0;
    int rect = -1;
    const bool hit = cast(uv, &t, &rect);
    // Keypoints near an occlusion edge (a neighbour pixel within the
    // threshold sees another surface) are outside the error model.
    bool edge = false;
    for (const Eigen::Vector2d& off : {Eigen::Vector2d(1, 0), Eigen::Vector2d(-1, 0),
                                       Eigen::Vector2d(0, 1), Eigen::Vector2d(0, -1)}) {
      double t2 = 0;
      int rect2 = -1;
      const bool hit2 = cast(uv + (options.pixel_threshold_px + 1.0) * off, &t2, &rect2);
      edge = edge || hit2 != hit || rect2 != rect;
    }
    if (!hit) {
      bool clear = true;  // far from any surface: no neighbour can be found
      for (const Eigen::Vector2d& off : {Eigen::Vector2d(20, 0), Eigen::Vector2d(-20, 0),
                                         Eigen::Vector2d(0, 20), Eigen::Vector2d(0, -20)}) {
        double t2 = 0;
        int rect2 = -1;
        clear = clear && !cast(uv + off, &t2, &rect2);
      }
      if (clear) {
        ++sky;
        sky_valid += got.valid;
      }
      continue;
    }
    if (edge) continue;
    ++surface;
    surface_far += t >= 3.0;
    if (!got.valid) continue;
    ++surface_valid;
    surface_far_valid += t >= 3.0;
    const Eigen::Vector3d b = camera.Unproject(uv);
    const Eigen::Vector3d truth_c = t * b;
    const double sin_alpha = std::abs((T_wg_c.linear() * b).dot(scene.rects()[rect].Normal()));
    const double delta = options.pixel_threshold_px * t / camera.params().fx;
    const double bound = 1.5 * delta * std::sqrt(1.0 - sin_alpha * sin_alpha) / sin_alpha + 0.005;
    const double error = (got.p_c - truth_c).norm();
    errors.push_back(error);
    within += error <= bound;
    EXPECT_LE(error, bound) << "uv " << uv.transpose() << " range " << t;
    // Consistent outputs: world point, camera point, depth, on the ray.
    EXPECT_LT((T_wg_c * got.p_c - got.p_in_wg).norm(), 1e-9);
    EXPECT_DOUBLE_EQ(got.depth_m, got.p_c.z());
    EXPECT_LT(got.p_c.normalized().cross(b).norm(), 1e-9);
    EXPECT_LE(got.reprojection_error_px, options.pixel_threshold_px);
  }
  std::sort(errors.begin(), errors.end());
  const double median = errors.empty() ? 0.0 : errors[errors.size() / 2];
  std::printf(
      "synthetic: %d surface keypoints, %.1f%% given depth (%.1f%% beyond 3 m), %d within "
      "bound, median error %.4f m, p90 %.4f m; %d clear-sky keypoints, %d given depth\n",
      surface, 100.0 * surface_valid / std::max(surface, 1),
      100.0 * surface_far_valid / std::max(surface_far, 1), within, median,
      errors.empty() ? 0.0 : errors[errors.size() * 9 / 10], sky, sky_valid);
  EXPECT_GT(surface, 2000);
  // Closer than ~3 m the 3 px disc around a keypoint (1.2 cm at 2 m) often
  // holds no map point at this density (~2500 points/m^2) and the ray slips
  // through to nothing (the floor has nothing behind it): those keypoints
  // get no depth, which is the method's behaviour, not a wrong depth.
  EXPECT_GE(surface_valid, 0.95 * surface);
  EXPECT_GE(surface_far_valid, 0.99 * surface_far);
  EXPECT_EQ(within, surface_valid);
  EXPECT_LT(median, 0.02);
  EXPECT_GT(sky, 300);
  EXPECT_EQ(sky_valid, 0);  // no depth where the ray hits nothing
}

TEST(DepthAssociationTest, EmptyMapAndNonFiniteKeypointsGiveNoDepth) {
  const VoxelGrid map;
  const DepthAssociator associator{Camera(Pinhole()), DepthAssociator::Options()};
  const DepthAssociationResult result = associator.Associate(
      map, Pose::Identity(), {Eigen::Vector2f(100, 100), Eigen::Vector2f(std::nanf(""), 3.0f)});
  ASSERT_EQ(result.keypoints.size(), 2u);
  EXPECT_FALSE(result.keypoints[0].valid);
  EXPECT_FALSE(result.keypoints[1].valid);
  EXPECT_EQ(result.num_valid, 0u);
  EXPECT_EQ(result.samples_queried, 0u);  // everything skipped as empty space
  EXPECT_DOUBLE_EQ(result.fraction_valid(), 0.0);
}

// A wall straight ahead: the answer is the first surface, not anything behind.
TEST(DepthAssociationTest, ReturnsTheFirstSurfaceAlongTheRay) {
  Scene scene;
  scene.AddRect(2, 4.0, Eigen::Vector2d(-1.5, -1.5), Eigen::Vector2d(1.5, 1.5));  // camera = world
  scene.AddRect(2, 9.0, Eigen::Vector2d(-9, -9), Eigen::Vector2d(9, 9));
  std::mt19937 rng(5);
  VoxelGrid::Options map_options;
  map_options.max_points_per_voxel = 40;
  VoxelGrid map(map_options);
  map.Insert(scene.Sample(4000.0, &rng), Eigen::Vector3d::Zero());
  DepthAssociator::Options options;
  options.pixel_threshold_px = 3.0;
  const DepthAssociator associator(Camera(Pinhole()), options);
  const std::vector<Eigen::Vector2f> keypoints = {
      {319.5f, 239.5f}, {250.0f, 200.0f}, {5.0f, 470.0f}};
  const auto result = associator.Associate(map, Pose::Identity(), keypoints);
  ASSERT_TRUE(result.keypoints[0].valid);
  EXPECT_NEAR(result.keypoints[0].depth_m, 4.0, 0.03);
  ASSERT_TRUE(result.keypoints[1].valid);
  EXPECT_NEAR(result.keypoints[1].depth_m, 4.0, 0.03);
  // This ray misses the near wall (|x| > 1.5 at z = 4) and meets the far one.
  ASSERT_TRUE(result.keypoints[2].valid);
  EXPECT_NEAR(result.keypoints[2].depth_m, 9.0, 0.06);
}

void ExpectSameAnswers(const DepthAssociationResult& fast, const DepthAssociationResult& ref,
                       const std::string& what) {
  ASSERT_EQ(fast.keypoints.size(), ref.keypoints.size());
  EXPECT_EQ(fast.num_valid, ref.num_valid) << what;
  for (size_t i = 0; i < ref.keypoints.size(); ++i) {
    const KeypointDepth& a = fast.keypoints[i];
    const KeypointDepth& b = ref.keypoints[i];
    ASSERT_EQ(a.valid, b.valid) << what << " keypoint " << i;
    if (!b.valid) continue;
    // Bit-identical: the fast march evaluates the same samples the same way.
    ASSERT_EQ(a.p_in_wg, b.p_in_wg) << what << " keypoint " << i;
    ASSERT_EQ(a.p_c, b.p_c) << what;
    ASSERT_EQ(a.reprojection_error_px, b.reprojection_error_px) << what;
  }
  // Every sample the reference queried was either queried or skipped.
  EXPECT_EQ(fast.samples_queried + fast.samples_skipped, ref.samples_queried) << what;
}

// The fast march against the reference on random scenes: random boxes,
// floating clutter points, camera models, poses, voxel sizes, skip blocks
// and options. Answers must be identical.
TEST(DepthAssociationTest, SkippingMarchEqualsReferenceOnRandomScenes) {
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::vector<int> skip_blocks = {8, 4, 16, 0, 12, 32};
  size_t total_valid = 0, total_skipped = 0, total_fast = 0, total_ref = 0;
  for (int trial = 0; trial < 18; ++trial) {
    Scene scene;
    scene.AddRect(2, 0.0, Eigen::Vector2d(-15, -15), Eigen::Vector2d(15, 15));
    const int boxes = 3 + trial % 6;
    for (int b = 0; b < boxes; ++b) {
      const Eigen::Vector3d lo(-12 + 24 * u(rng), -12 + 24 * u(rng), 0.0);
      const Eigen::Vector3d size(0.3 + 3 * u(rng), 0.3 + 3 * u(rng), 0.3 + 3 * u(rng));
      scene.AddBox(lo, lo + size);
    }
    VoxelGrid::Options map_options;
    map_options.voxel_size_m = std::vector<double>{0.1, 0.07, 0.2}[trial % 3];
    map_options.skip_block_voxels = skip_blocks[trial % skip_blocks.size()];
    map_options.max_points_per_voxel = 5 + trial % 20;
    VoxelGrid map(map_options);
    std::vector<Eigen::Vector3f> points = scene.Sample(200.0 + 200.0 * (trial % 5), &rng);
    for (int i = 0; i < 400; ++i) {  // clutter: isolated points in the air
      points.emplace_back(-15 + 30 * u(rng), -15 + 30 * u(rng), 4 * u(rng));
    }
    map.Insert(points, Eigen::Vector3d::Zero());

    const Camera camera(trial % 3 == 2 ? Fisheye() : Pinhole({-0.2, 0.05, 0.001, -0.0005}));
    DepthAssociator::Options options;
    options.step_m = std::vector<double>{0.05, 0.03, 0.11}[trial % 3];
    options.min_range_m = 0.2 + u(rng);
    options.max_range_m = 20.0 + 20.0 * u(rng);
    options.pixel_threshold_px = std::vector<double>{2.0, 1.0, 6.0}[trial % 3];
    options.neighborhood = std::vector<int>{27, 19, 7}[(trial / 3) % 3];
    options.max_neighbor_distance_m = 0.05 + 0.25 * u(rng);
    const DepthAssociator associator(camera, options);

    Pose T_wg_c = Pose::Identity();
    if (trial % 4 == 3) {
      // Axis-aligned camera exactly on block boundaries: rays parallel to
      // block faces, origin on a face.
      T_wg_c = ForwardCamera(Eigen::Vector3d(-8.0, 1.6, 1.6), 0.0);
    } else {
      const Eigen::Vector3d axis = Eigen::Vector3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
      T_wg_c = ForwardCamera(
          Eigen::Vector3d(-10 + 20 * u(rng), -10 + 20 * u(rng), 0.5 + 2 * u(rng)), 0.3 * u(rng));
      T_wg_c.linear() = Eigen::AngleAxisd(2 * M_PI * u(rng), Eigen::Vector3d::UnitZ()) *
                        Eigen::AngleAxisd(0.3 * u(rng), axis.normalized()) * T_wg_c.linear();
    }
    std::vector<Eigen::Vector2f> keypoints = {{320.0f, 240.0f}, {319.5f, 239.5f}};
    for (int i = 0; i < 250; ++i) keypoints.emplace_back(640 * u(rng), 480 * u(rng));

    const auto fast = associator.Associate(map, T_wg_c, keypoints);
    const auto ref = associator.AssociateReference(map, T_wg_c, keypoints);
    ExpectSameAnswers(fast, ref, "trial " + std::to_string(trial));
    total_valid += ref.num_valid;
    total_skipped += fast.samples_skipped;
    total_fast += fast.samples_queried;
    total_ref += ref.samples_queried;
  }
  std::printf(
      "random scenes: %zu valid keypoints; samples queried: reference %zu, fast %zu "
      "(%zu skipped)\n",
      total_valid, total_ref, total_fast, total_skipped);
  EXPECT_GT(total_valid, 1000u);
  EXPECT_LT(total_fast * 5, total_ref);  // skipping actually skips
}

TEST(DepthAssociationTest, OptionsCheckNamesTheField) {
  DepthAssociator::Options options;
  options.max_range_m = options.min_range_m;
  test::ExpectOptionErrorNaming("max_range_m",
                                [&] { DepthAssociator associator(Camera(Pinhole()), options); });
}

}  // namespace
}  // namespace ag
