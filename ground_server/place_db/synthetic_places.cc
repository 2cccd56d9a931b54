#include "ground_server/place_db/synthetic_places.h"

#include <algorithm>
#include <cmath>

namespace ag {

namespace {

constexpr int kInputs = 5;  // x, y, z, cos(yaw), sin(yaw)

void Normalise(std::vector<float>& v) {
  double n2 = 0;
  for (float x : v) n2 += double{x} * x;
  const double scale = n2 > 0 ? 1.0 / std::sqrt(n2) : 0.0;
  for (float& x : v) x = static_cast<float>(x * scale);
}

}  // namespace

SyntheticPlaces::SyntheticPlaces(Options options) : options_(options) {
  std::mt19937 rng(options_.seed);
  std::normal_distribution<float> normal(0.0F, 1.0F);
  std::uniform_real_distribution<float> phase(0.0F, static_cast<float>(2 * M_PI));
  w_.resize(static_cast<size_t>(options_.dim) * kInputs);
  b_.resize(static_cast<size_t>(options_.dim));
  for (float& w : w_) w = normal(rng);
  for (float& b : b_) b = phase(rng);
}

std::vector<float> SyntheticPlaces::Descriptor(const Eigen::Vector3d& p_w, double yaw, double noise,
                                               std::mt19937& rng) const {
  const double u[kInputs] = {p_w.x() / options_.place_scale_m, p_w.y() / options_.place_scale_m,
                             p_w.z() / options_.place_scale_m,
                             std::cos(yaw) / options_.yaw_scale_rad,
                             std::sin(yaw) / options_.yaw_scale_rad};
  const int dim = options_.dim;
  const double amplitude = std::sqrt(2.0 / dim);
  std::normal_distribution<double> normal(0.0, noise / std::sqrt(static_cast<double>(dim)));
  std::vector<float> d(static_cast<size_t>(dim));
  for (int j = 0; j < dim; ++j) {
    double arg = b_[static_cast<size_t>(j)];
    for (int i = 0; i < kInputs; ++i)
      arg += w_[static_cast<size_t>(j) * kInputs + static_cast<size_t>(i)] * u[i];
    d[static_cast<size_t>(j)] =
        static_cast<float>(amplitude * std::cos(arg) + (noise > 0 ? normal(rng) : 0.0));
  }
  Normalise(d);
  return d;
}

std::vector<float> SyntheticPlaces::Descriptor(const Pose& T_w_c, double noise,
                                               std::mt19937& rng) const {
  const Eigen::Vector3d axis_w = T_w_c.linear().col(2);  // optical axis
  return Descriptor(T_w_c.translation(), std::atan2(axis_w.y(), axis_w.x()), noise, rng);
}

std::vector<Pose> SyntheticFlight(int keyframes, double step_m, double area_m, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> turn(0.0, 0.15);  // rad per keyframe
  std::normal_distribution<double> climb(0.0, 0.2);  // m per keyframe
  std::uniform_real_distribution<double> start(0.0, area_m);
  // Body (x forward, y left, z up) from camera (x right, y down, z forward),
  // then the camera pitched 30 deg down.
  Eigen::Matrix3d R_b_c;
  R_b_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Matrix3d R_pitch = Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitY()).matrix();
  Eigen::Vector3d p(start(rng), start(rng), 30.0);
  double yaw = std::uniform_real_distribution<double>(-M_PI, M_PI)(rng);
  std::vector<Pose> poses;
  poses.reserve(static_cast<size_t>(std::max(keyframes, 0)));
  for (int i = 0; i < keyframes; ++i) {
    Pose T = Pose::Identity();
    T.linear() = RotZ(yaw) * R_pitch * R_b_c;
    T.translation() = p;
    poses.push_back(T);
    yaw = WrapAngle(yaw + turn(rng));
    const Eigen::Vector3d ahead = p + step_m * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0);
    if (ahead.x() < 0 || ahead.x() > area_m || ahead.y() < 0 || ahead.y() > area_m) {
      yaw = WrapAngle(yaw + M_PI / 2);  // turn away from the border
    }
    p += step_m * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0);
    p.z() = std::clamp(p.z() + climb(rng), 15.0, 60.0);
  }
  return poses;
}

std::vector<float> RandomUnitVector(int dim, std::mt19937& rng) {
  std::normal_distribution<float> normal(0.0F, 1.0F);
  std::vector<float> v(static_cast<size_t>(dim));
  for (float& x : v) x = normal(rng);
  Normalise(v);
  return v;
}

AirKeyframe SyntheticKeyframe(const std::string& agent, int64_t seq, const Pose& T_wa_c,
                              std::vector<float> global, int keypoints, int local_dim,
                              std::mt19937& rng) {
  AirKeyframe kf;
  kf.agent = agent;
  kf.seq = seq;
  kf.t_ns = 1'000'000'000LL + seq * 200'000'000LL;  // 5 keyframes per second
  kf.camera_id = agent + "_cam0";
  kf.T_wa_c = T_wa_c;
  kf.global_descriptor = std::move(global);
  std::uniform_real_distribution<float> pixel(0.0F, 640.0F);
  std::uniform_real_distribution<float> unit(0.0F, 1.0F);
  LocalFeatures& f = kf.features;
  f.descriptor_type = "xfeat";
  for (int i = 0; i < keypoints; ++i) {
    f.keypoints.emplace_back(pixel(rng), pixel(rng) * 0.75F);
    f.scores.push_back(unit(rng));
  }
  if (keypoints > 0) {
    f.descriptors.create(keypoints, local_dim, CV_32F);
    for (int r = 0; r < keypoints; ++r) {
      const std::vector<float> row = RandomUnitVector(local_dim, rng);
      std::copy(row.begin(), row.end(), f.descriptors.ptr<float>(r));
    }
  }
  return kf;
}

}  // namespace ag
