#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>
#include <vector>

#include "common/camera/camera.h"
#include "tools/sim/lidar.h"
#include "tools/sim/random.h"
#include "tools/sim/renderer.h"
#include "tools/sim/world.h"

namespace ag {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

/// A yawed box in front of the camera (oblique faces make sub-pixel shifts
/// visible in depth) on the ground plane.
SimWorld BoxWorld() {
  SimWorld world(9);
  SimObject box;
  box.shape = SimObject::Shape::kBox;
  box.center = Vector3d(7.0, 0.4, 1.2);
  box.half = Vector3d(1.2, 1.6, 1.2);
  box.yaw = 0.6;
  world.AddObject(box, MaterialKind::kConcrete, MaterialKind::kRoof);
  world.BuildIndex();
  return world;
}

/// Signed distance of a point to the box of BoxWorld (0 on its surface).
double BoxDistance(const SimObject& b, const Vector3d& p_w) {
  const Vector3d q0 = p_w - b.center;
  const Vector3d q(b.cos_yaw * q0.x() + b.sin_yaw * q0.y(),
                   -b.sin_yaw * q0.x() + b.cos_yaw * q0.y(), q0.z());
  return (q.cwiseAbs() - b.half).maxCoeff();
}

struct CameraCase {
  const char* model;
  std::vector<double> distortion;
  double f;
};

void PrintTo(const CameraCase& c, std::ostream* os) { *os << c.model << " f=" << c.f; }

class SimRenderExactness : public ::testing::TestWithParam<CameraCase> {};

TEST_P(SimRenderExactness, DepthImageAgreesWithTheCameraModel) {
  const SimWorld world = BoxWorld();
  const SimObject& box = world.objects().front();
  CameraSimOptions options;
  options.model = GetParam().model;
  options.distortion = GetParam().distortion;
  options.fx = options.fy = GetParam().f;
  options.pitch_down_deg = 8.0;
  options.position_m = {0.0, 0.0, 0.0};
  const CameraRenderer renderer(options);
  const Camera camera(options.Params());
  Pose T_W_body = Pose::Identity();
  T_W_body.translation() = Vector3d(0.0, 0.0, 1.3);
  const Pose T_W_camera = T_W_body * options.NominalBodyCamera();
  SimRandom rng(1);
  const CameraRenderer::Frame frame = renderer.Render(world, T_W_camera, rng);
  ASSERT_EQ(frame.depth.type(), CV_32FC1);

  // 1. Every pixel's depth, back-projected through the camera model, lies on
  //    the world's surface.
  int box_pixels = 0, ground_pixels = 0;
  for (int v = 0; v < frame.depth.rows; ++v) {
    for (int u = 0; u < frame.depth.cols; ++u) {
      const float z = frame.depth.at<float>(v, u);
      if (z <= 0.0f) continue;
      const Vector3d b = camera.Unproject(Vector2d(u, v));
      const Vector3d p_w = T_W_camera * (b * (z / b.z()));
      const double to_ground = std::fabs(p_w.z());
      const double to_box = std::fabs(BoxDistance(box, p_w));
      ASSERT_LT(std::min(to_ground, to_box), 2e-5 * z + 1e-5) << "pixel " << u << "," << v;
      (to_box < to_ground ? box_pixels : ground_pixels)++;
    }
  }
  EXPECT_GT(box_pixels, 5000);
  EXPECT_GT(ground_pixels, 5000);

  // 2. Known world points on the box faces project (Camera::Project, true
  //    pose) to where the rendered depth has them: the inverse depth, which
  //    is affine across a plane, interpolated at the projected sub-pixel
  //    position equals the point's own. A shift of 0.05 px would show.
  const Pose T_camera_W = T_W_camera.inverse();
  SimRandom points(3);
  int checked = 0;
  for (int i = 0; i < 4000; ++i) {
    // A random point on a random side face or the top.
    const int face = points.UniformInt(0, 4);
    Vector3d q(points.Uniform(-1, 1) * box.half.x(), points.Uniform(-1, 1) * box.half.y(),
               points.Uniform(-1, 1) * box.half.z());
    if (face < 4)
      q[face / 2] = (face % 2 == 0 ? 1.0 : -1.0) * box.half[face / 2];
    else
      q.z() = box.half.z();
    const Vector3d p_w = box.center + Vector3d(box.cos_yaw * q.x() - box.sin_yaw * q.y(),
                                               box.sin_yaw * q.x() + box.cos_yaw * q.y(), q.z());
    const Vector3d p_c = T_camera_W * p_w;
    Vector2d uv;
    if (!camera.Project(p_c, &uv) || !camera.InImage(uv, 2.0)) continue;
    const int u0 = static_cast<int>(std::floor(uv.x())), v0 = static_cast<int>(std::floor(uv.y()));
    // All four neighbours must see this same face (not an edge, not occluded).
    bool same = true;
    double inv[4];
    for (int k = 0; k < 4; ++k) {
      const int u = u0 + (k & 1), v = v0 + (k >> 1);
      const float z = frame.depth.at<float>(v, u);
      if (z <= 0.0f) {
        same = false;
        break;
      }
      const Vector3d b = camera.Unproject(Vector2d(u, v));
      const Vector3d n_w = T_W_camera * (b * (z / b.z()));
      const Vector3d n0 = n_w - box.center;
      const Vector3d nq(box.cos_yaw * n0.x() + box.sin_yaw * n0.y(),
                        -box.sin_yaw * n0.x() + box.cos_yaw * n0.y(), n0.z());
      const int axis = face / 2;
      if (std::fabs(BoxDistance(box, n_w)) > 1e-4 ||
          std::fabs(std::fabs(nq[axis]) - box.half[axis]) > 1e-4 || nq[axis] * q[axis] < 0) {
        same = false;
        break;
      }
      inv[k] = 1.0 / z;
    }
    if (!same) continue;
    const double fu = uv.x() - u0, fv = uv.y() - v0;
    const double inv_interp =
        (1 - fv) * ((1 - fu) * inv[0] + fu * inv[1]) + fv * ((1 - fu) * inv[2] + fu * inv[3]);
    EXPECT_NEAR(1.0 / inv_interp, p_c.z(), 2e-4 * p_c.z()) << "point " << i;
    ++checked;
  }
  EXPECT_GT(checked, 300);

  // 3. The box's top corners: the projected corner separates box and
  //    background, i.e. within a pixel of it there are box and non-box pixels.
  for (double sx : {-1.0, 1.0}) {
    for (double sy : {-1.0, 1.0}) {
      const Vector3d q(sx * box.half.x(), sy * box.half.y(), box.half.z());
      const Vector3d p_w = box.center + Vector3d(box.cos_yaw * q.x() - box.sin_yaw * q.y(),
                                                 box.sin_yaw * q.x() + box.cos_yaw * q.y(), q.z());
      Vector2d uv;
      if (!camera.Project(T_camera_W * p_w, &uv) || !camera.InImage(uv, 3.0)) continue;
      int on_box = 0, off_box = 0;
      for (int dv = -1; dv <= 1; ++dv) {
        for (int du = -1; du <= 1; ++du) {
          const int u = static_cast<int>(std::lround(uv.x())) + du,
                    v = static_cast<int>(std::lround(uv.y())) + dv;
          const float z = frame.depth.at<float>(v, u);
          const Vector3d b = camera.Unproject(Vector2d(u, v));
          const bool box_hit =
              z > 0 && std::fabs(BoxDistance(box, T_W_camera * (b * (z / b.z())))) < 1e-4;
          (box_hit ? on_box : off_box)++;
        }
      }
      // A corner hidden behind the box itself shows box pixels only.
      if (T_camera_W.linear().row(2).dot(p_w - T_W_camera.translation()) > 0 && off_box > 0) {
        EXPECT_GT(on_box, 0) << "corner " << sx << "," << sy;
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    Cameras, SimRenderExactness,
    ::testing::Values(CameraCase{"pinhole", {-0.08, 0.02, 0.001, -0.0005}, 500.0},
                      CameraCase{"pinhole", {}, 420.0},
                      CameraCase{"equidistant", {0.05, -0.01, 0.003, -0.001}, 280.0}),
    [](const ::testing::TestParamInfo<CameraCase>& info) {
      return std::string(info.param.model) + std::to_string(info.index);
    });

TEST(SimRender, ImagesHaveTextureNoiseAndRespectExposure) {
  WorldOptions wo;
  const SimWorld world = SimWorld::Generate(wo, 5, {});
  CameraSimOptions options;
  const CameraRenderer renderer(options);
  Pose T_W_body = Pose::Identity();
  T_W_body.translation() = Vector3d(0, 0, 3.0);
  options.pitch_down_deg = 30.0;
  const Pose T = T_W_body * options.NominalBodyCamera();
  SimRandom rng_a(1), rng_b(1), rng_c(2);
  const auto a = renderer.Render(world, T, rng_a);
  const auto b = renderer.Render(world, T, rng_b);
  const auto c = renderer.Render(world, T, rng_c);
  ASSERT_EQ(a.image.type(), CV_8UC1);
  EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_L1), 0.0);  // same noise stream, same image
  const double noise =
      cv::norm(a.image, c.image, cv::NORM_L1) / static_cast<double>(a.image.total());
  EXPECT_GT(noise, 0.3);   // sensor noise differs between streams...
  EXPECT_LT(noise, 12.0);  // ...but the scene is the same
  cv::Scalar mean, stddev;
  cv::meanStdDev(a.image, mean, stddev);
  EXPECT_GT(mean[0], 60.0);  // auto exposure
  EXPECT_LT(mean[0], 200.0);
  EXPECT_GT(stddev[0], 15.0);  // textured, not flat
}

TEST(SimLidar, NoiseFreeSweepLiesOnTheSurfacesTheCameraSees) {
  WorldOptions wo;
  wo.size_x_m = 40;
  wo.size_y_m = 40;
  const SimWorld world = SimWorld::Generate(wo, 8, {});
  LidarOptions lo;
  lo.range_noise_m = 0.0;
  lo.dropout = 0.0;
  lo.beams = 32;
  // The platform moves during the sweep; points come back in the frame at
  // the sweep's end, so they must match the depth seen from that pose.
  auto T_W_lidar = [](double tau) {
    Pose T = Pose::Identity();
    T.linear() = RotZ(0.3 * tau);
    T.translation() = Vector3d(1.5 * tau, 0.2 * tau, 0.8);
    return T;
  };
  SimRandom rng(4);
  const LidarSweep sweep = SimulateLidarSweep(world, lo, T_W_lidar, 1.0, rng);
  ASSERT_GT(sweep.points.size(), 10000u);
  ASSERT_EQ(sweep.points.size(), sweep.intensity.size());
  const Pose T_end = T_W_lidar(1.0);
  int checked = 0;
  for (size_t i = 0; i < sweep.points.size(); i += 7) {
    const Vector3d p_w = T_end * sweep.points[i].cast<double>();
    // Cast from the sweep-end pose towards the point: the first hit must be
    // the point itself, unless another surface hides it from there.
    const Vector3d to = p_w - T_end.translation();
    RayHit hit;
    if (!world.Cast(T_end.translation(), to.normalized(), 1e3, &hit)) continue;
    if (hit.t < to.norm() - 0.01) continue;  // occluded from the end pose
    EXPECT_NEAR(hit.t, to.norm(), 1e-4) << "point " << i;
    ++checked;
  }
  EXPECT_GT(checked, 1000);
}

}  // namespace
}  // namespace ag
