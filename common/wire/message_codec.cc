#include "common/wire/message_codec.h"

#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/camera/camera.h"
#include "common/core/agent_name.h"
#include "common/core/error.h"

namespace ag {
namespace {

bool Fail(std::string* error, const std::string& what) {
  *error = what;
  return false;
}

// Unit quaternion (w, x, y, z) and position to a pose; false if invalid.
bool PoseFrom(const double* position, const double* wxyz, Pose* T) {
  Eigen::Quaterniond q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
  const Eigen::Vector3d t(position[0], position[1], position[2]);
  if (!q.coeffs().allFinite() || !t.allFinite() || std::abs(q.norm() - 1.0) > 1e-3) return false;
  *T = Pose::Identity();
  T->linear() = q.normalized().toRotationMatrix();
  T->translation() = t;
  return true;
}

void PoseTo(const Pose& T, double* position, double* wxyz) {
  const Eigen::Quaterniond q(T.linear());
  for (int i = 0; i < 3; ++i) position[i] = T.translation()[i];
  wxyz[0] = q.w();
  wxyz[1] = q.x();
  wxyz[2] = q.y();
  wxyz[3] = q.z();
}

}  // namespace

bool DecodeCameraInfo(const aglcm::camera_info_t& msg, CameraInfo* info, std::string* error) {
  const std::string who = "camera_info from '" + msg.agent + "' camera '" + msg.camera_id + "': ";
  if (!IsValidAgentName(msg.agent)) return Fail(error, who + "invalid agent name");
  if (msg.camera_id.empty()) return Fail(error, who + "empty camera_id");
  if (msg.num_distortion != static_cast<int>(msg.distortion.size())) {
    return Fail(error, who + "num_distortion does not match the array");
  }
  CameraInfo out;
  out.agent = msg.agent;
  out.camera_id = msg.camera_id;
  out.params.model = msg.model;
  out.params.width = msg.width;
  out.params.height = msg.height;
  out.params.fx = msg.intrinsics[0];
  out.params.fy = msg.intrinsics[1];
  out.params.cx = msg.intrinsics[2];
  out.params.cy = msg.intrinsics[3];
  out.params.distortion = msg.distortion;
  try {
    const Camera check(out.params);
  } catch (const std::exception& e) {
    return Fail(error, who + e.what());
  }
  if (msg.has_T_body_camera) {
    Eigen::Matrix4d M;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) M(r, c) = msg.T_body_camera[r][c];
    }
    if (!M.allFinite() || !IsRotation(M.topLeftCorner<3, 3>(), 1e-3) ||
        (M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
      return Fail(error, who + "T_body_camera is not a rigid transform");
    }
    out.has_T_body_camera = true;
    out.T_body_camera.matrix() = M;
  }
  if (!std::isfinite(msg.time_offset_s)) return Fail(error, who + "non-finite time_offset_s");
  out.time_offset_s = msg.time_offset_s;
  *info = out;
  return true;
}

aglcm::relative_pose_t EncodeRelativePose(const RelativePoseEstimate& e) {
  aglcm::relative_pose_t m;
  m.agent = e.agent;
  m.ground_agent = e.ground_agent;
  m.seq = e.seq;
  m.t_ns = e.t_ns;
  m.air_t_ns = e.air_t_ns;
  m.air_seq = e.air_seq;
  m.status = e.status;
  m.status_reason = e.status_reason;
  m.x = e.T_wa_wg.translation().x();
  m.y = e.T_wa_wg.translation().y();
  m.z = e.T_wa_wg.translation().z();
  m.yaw = ProjectedYaw(e.T_wa_wg.linear());
  const Eigen::Matrix4d T = MakePose4Dof(m.x, m.y, m.z, m.yaw).matrix();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      m.T_wa_wg[r][c] = T(r, c);
      m.covariance[r][c] = e.covariance(r, c);
    }
  }
  m.num_inliers = e.num_inliers;
  m.num_keyframe_pairs = e.num_keyframe_pairs;
  m.rms_reprojection_error_px = static_cast<float>(e.rms_reprojection_error_px);
  m.latency_s = static_cast<float>(e.latency_s);
  m.solve_time_s = static_cast<float>(e.solve_time_s);
  return m;
}

bool DecodeRelativePose(const aglcm::relative_pose_t& m, RelativePoseEstimate* out,
                        std::string* error) {
  if (!IsValidAgentName(m.agent)) return Fail(error, "relative_pose: invalid agent name");
  if (m.status < aglcm::relative_pose_t::INITIALIZING || m.status > aglcm::relative_pose_t::LOST) {
    return Fail(error, "relative_pose: unknown status " + std::to_string(m.status));
  }
  if (!std::isfinite(m.x) || !std::isfinite(m.y) || !std::isfinite(m.z) || !std::isfinite(m.yaw)) {
    return Fail(error, "relative_pose: non-finite pose");
  }
  RelativePoseEstimate e;
  e.agent = m.agent;
  e.ground_agent = m.ground_agent;
  e.seq = m.seq;
  e.t_ns = m.t_ns;
  e.air_t_ns = m.air_t_ns;
  e.air_seq = m.air_seq;
  e.status = m.status;
  e.status_reason = m.status_reason;
  e.T_wa_wg = MakePose4Dof(m.x, m.y, m.z, m.yaw);
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) e.covariance(r, c) = m.covariance[r][c];
  }
  e.num_inliers = m.num_inliers;
  e.num_keyframe_pairs = m.num_keyframe_pairs;
  e.rms_reprojection_error_px = m.rms_reprojection_error_px;
  e.latency_s = m.latency_s;
  e.solve_time_s = m.solve_time_s;
  *out = e;
  return true;
}

aglcm::odometry_t EncodeOdometry(const StampedPose& pose, const std::string& world_frame,
                                 const std::string& body_frame) {
  aglcm::odometry_t m{};
  m.t_ns = pose.t_ns;
  m.world_frame_id = world_frame;
  m.body_frame_id = body_frame;
  PoseTo(pose.T, m.position, m.orientation);
  m.has_twist = false;
  m.has_pose_covariance = false;
  return m;
}

bool DecodeOdometry(const aglcm::odometry_t& m, StampedPose* pose, std::string* error) {
  StampedPose p;
  p.t_ns = m.t_ns;
  if (!PoseFrom(m.position, m.orientation, &p.T)) {
    return Fail(error, "odometry at t_ns " + std::to_string(m.t_ns) +
                           ": non-finite position or non-unit quaternion");
  }
  *pose = p;
  return true;
}

aglcm::image_t EncodeImagePng(int64_t t_ns, const std::string& frame_id, const cv::Mat& image) {
  aglcm::image_t m;
  m.t_ns = t_ns;
  m.frame_id = frame_id;
  m.width = image.cols;
  m.height = image.rows;
  m.encoding = "png";
  m.step = 0;
  cv::imencode(".png", image, m.data);
  m.num_bytes = static_cast<int32_t>(m.data.size());
  return m;
}

bool DecodeImage(const aglcm::image_t& m, cv::Mat* image, std::string* error) {
  const std::string who = "image '" + m.frame_id + "' at t_ns " + std::to_string(m.t_ns) + ": ";
  if (m.num_bytes != static_cast<int>(m.data.size()))
    return Fail(error, who + "num_bytes mismatch");
  if (m.width <= 0 || m.height <= 0 || m.width > 16384 || m.height > 16384) {
    return Fail(error, who + "implausible size " + std::to_string(m.width) + "x" +
                           std::to_string(m.height));
  }
  cv::Mat out;
  if (m.encoding == "png" || m.encoding == "jpeg") {
    out = cv::imdecode(m.data, cv::IMREAD_UNCHANGED);
    if (out.empty()) return Fail(error, who + "cannot decode " + m.encoding + " data");
  } else {
    int type = 0, channels = 0;
    if (m.encoding == "mono8") {
      type = CV_8UC1, channels = 1;
    } else if (m.encoding == "bgr8" || m.encoding == "rgb8") {
      type = CV_8UC3, channels = 3;
    } else {
      return Fail(error, who + "unknown encoding '" + m.encoding + "'");
    }
    if (m.step < m.width * channels ||
        static_cast<int64_t>(m.step) * m.height > static_cast<int64_t>(m.data.size())) {
      return Fail(error, who + "step/size do not fit the data");
    }
    out = cv::Mat(m.height, m.width, type, const_cast<uint8_t*>(m.data.data()), m.step).clone();
    if (m.encoding == "rgb8") cv::cvtColor(out, out, cv::COLOR_RGB2BGR);
  }
  if (out.cols != m.width || out.rows != m.height) {
    return Fail(error, who + "decoded size differs from width/height");
  }
  *image = out;
  return true;
}

aglcm::point_cloud_t EncodePointCloud(int64_t t_ns, const std::string& frame_id,
                                      const std::vector<Eigen::Vector3f>& points,
                                      const std::vector<float>& intensity) {
  aglcm::point_cloud_t m;
  m.t_ns = t_ns;
  m.frame_id = frame_id;
  m.num_points = static_cast<int32_t>(points.size());
  m.x.resize(points.size());
  m.y.resize(points.size());
  m.z.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    m.x[i] = points[i].x();
    m.y[i] = points[i].y();
    m.z[i] = points[i].z();
  }
  m.intensity = intensity.size() == points.size() ? intensity : std::vector<float>{};
  m.num_intensities = static_cast<int32_t>(m.intensity.size());
  return m;
}

bool DecodePointCloud(const aglcm::point_cloud_t& m, std::vector<Eigen::Vector3f>* points,
                      std::vector<float>* intensity, std::string* error) {
  const size_t n = static_cast<size_t>(std::max(m.num_points, 0));
  if (m.num_points < 0 || m.x.size() != n || m.y.size() != n || m.z.size() != n) {
    return Fail(error, "point cloud at t_ns " + std::to_string(m.t_ns) +
                           ": arrays do not match num_points");
  }
  if (m.num_intensities != 0 && static_cast<size_t>(m.num_intensities) != n) {
    return Fail(error, "point cloud: num_intensities must be 0 or num_points");
  }
  points->clear();
  points->reserve(n);
  intensity->clear();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p(m.x[i], m.y[i], m.z[i]);
    // Sensors mark missing returns with NaN: drop those points, keep the rest.
    if (!p.allFinite()) continue;
    points->push_back(p);
    if (m.num_intensities > 0) intensity->push_back(m.intensity[i]);
  }
  return true;
}

}  // namespace ag
