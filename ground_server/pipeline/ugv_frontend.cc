#include "ground_server/pipeline/ugv_frontend.h"

#include <chrono>

#include "ground_server/place_db/place_db.h"

namespace ag {
namespace {

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace

void UgvFrontend::Options::Check() const {
  CheckOption(min_depth_fraction >= 0 && min_depth_fraction <= 1, "min_depth_fraction",
              "must be in [0, 1]");
  CheckOption(twist_half_window_s > 0 && twist_half_window_s <= 1, "twist_half_window_s",
              "must be in (0, 1] s");
}

UgvFrontend::UgvFrontend(const AgentCalibration& calibration, const FeatureExtractor* features,
                         const GlobalDescriptorExtractor* global, const Options& options)
    : camera_mount_{calibration.camera.T_body_camera, calibration.camera.time_offset_s},
      camera_(std::make_shared<Camera>(calibration.camera.camera)),
      features_(features),
      global_(global),
      options_(options),
      depth_(*camera_, options.depth) {
  options_.Check();
  if (calibration.lidar) {
    lidar_mount_ = {calibration.lidar->T_body_lidar, calibration.lidar->time_offset_s};
  }
}

UgvFrontend::Result UgvFrontend::Process(int64_t id, int64_t t_camera_ns, const cv::Mat& image,
                                         const OdometryBuffer& odometry,
                                         const VoxelMap& map) const {
  Result result;
  const PoseLookup pose = odometry.SensorPoseAt(t_camera_ns, camera_mount_);
  result.status = pose.status;
  if (!pose.ok()) return result;
  auto kf = std::make_shared<UgvKeyframe>();
  kf->id = id;
  kf->t_ns = t_camera_ns;
  kf->T_wg_c = pose.T;
  const SensorTwist twist =
      odometry.SensorTwistAt(t_camera_ns, camera_mount_, options_.twist_half_window_s);
  kf->omega_c = twist.omega;
  kf->v_wg = twist.v_wg;
  auto start = std::chrono::steady_clock::now();
  kf->features = features_->Extract(image);
  result.features_ms = MsSince(start);
  start = std::chrono::steady_clock::now();
  kf->global_descriptor = global_->Compute(image, kf->features);
  result.global_ms = MsSince(start);
  start = std::chrono::steady_clock::now();
  const size_t n = kf->features.size();
  kf->points_wg.resize(n);
  kf->has_point.resize(n);
  kf->planes_wg.assign(n, Eigen::Vector4d::Zero());
  {
    const VoxelMap::Reader reader = map.Read();
    const DepthAssociationResult depth =
        depth_.Associate(reader.grid(), kf->T_wg_c, kf->features.keypoints);
    for (size_t i = 0; i < n; ++i) {
      const KeypointDepth& d = depth.keypoints[i];
      kf->has_point[i] = d.valid ? 1 : 0;
      kf->points_wg[i] = d.p_in_wg;
      if (!d.valid || !options_.fit_planes) continue;
      if (const auto plane = FitLocalPlane(reader.grid(), d.p_in_wg, options_.plane)) {
        kf->planes_wg[i] << plane->normal, -plane->normal.dot(plane->point);
      }
    }
  }
  result.depth_ms = MsSince(start);
  result.keyframe = std::move(kf);
  return result;
}

PoseLookupStatus UgvFrontend::ImageReady(int64_t t_camera_ns,
                                         const OdometryBuffer& odometry) const {
  const PoseLookupStatus at = odometry.SensorPoseAt(t_camera_ns, camera_mount_).status;
  if (at != PoseLookupStatus::kOk) return at;
  const int64_t later = t_camera_ns + static_cast<int64_t>(options_.twist_half_window_s * 1e9);
  return odometry.SensorPoseAt(later, camera_mount_).status == PoseLookupStatus::kWait
             ? PoseLookupStatus::kWait
             : PoseLookupStatus::kOk;
}

PoseLookupStatus UgvFrontend::PoseScan(int64_t t_lidar_ns, std::vector<Eigen::Vector3f> points_l,
                                       const OdometryBuffer& odometry, PosedScan* scan) const {
  const PoseLookup pose = odometry.SensorPoseAt(t_lidar_ns, lidar_mount_);
  if (!pose.ok()) return pose.status;
  scan->t_ns = t_lidar_ns;
  scan->points_l = std::move(points_l);
  scan->T_wg_lidar = pose.T;
  return PoseLookupStatus::kOk;
}

std::vector<AirKeyframeSource::Candidate> PlaceDbSource::Retrieve(const std::vector<float>& global,
                                                                  const std::string& agent,
                                                                  int k) const {
  std::vector<Candidate> out;
  const PlaceDb::QueryResult q = db_->Query(global, k, agent);
  if (!q.success) return out;
  for (const PlaceDb::Match& m : q.matches) out.push_back({m.entry.keyframe, m.similarity});
  return out;
}

std::vector<std::shared_ptr<const AirKeyframe>> PlaceDbSource::Recent(const std::string& agent,
                                                                      int n) const {
  std::vector<std::shared_ptr<const AirKeyframe>> out;
  const std::vector<PlaceDb::Id> ids = db_->Ids(agent);
  for (auto it = ids.rbegin(); it != ids.rend() && static_cast<int>(out.size()) < n; ++it) {
    if (auto kf = db_->Get(*it)) out.push_back(std::move(kf));
  }
  return out;
}

}  // namespace ag
