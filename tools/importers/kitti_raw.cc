#include "tools/importers/kitti_raw.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "common/core/error.h"

namespace ag {
namespace {

// Earth radius of the devkit's latlonToMercator.m (WGS84 equatorial, m).
constexpr double kEarthRadiusM = 6378137.0;

// KITTI calibration files carry 7 significant digits: their rotations are
// orthonormal to about 1e-7 per entry; more than this is a broken file.
constexpr double kCalibRotationTolerance = 1e-5;

bool ParseFixedDigits(const std::string& text, size_t begin, size_t count, int64_t* value) {
  if (begin + count > text.size()) return false;
  int64_t v = 0;
  for (size_t i = begin; i < begin + count; ++i) {
    if (text[i] < '0' || text[i] > '9') return false;
    v = v * 10 + (text[i] - '0');
  }
  *value = v;
  return true;
}

bool IsLeapYear(int64_t y) { return (y % 4 == 0 && y % 100 != 0) || y % 400 == 0; }

int64_t DaysInMonth(int64_t y, int64_t m) {
  static constexpr int64_t kDays[12] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return m == 2 && IsLeapYear(y) ? 29 : kDays[m - 1];
}

// Days from 1970-01-01 to y-m-d in the proleptic Gregorian calendar (Howard
// Hinnant's days_from_civil), exact for every year this format can hold.
int64_t DaysFromCivil(int64_t y, int64_t m, int64_t d) {
  y -= m <= 2 ? 1 : 0;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const int64_t yoe = y - era * 400;
  const int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

std::string TrimRight(std::string text) {
  while (!text.empty() && (text.back() == '\r' || text.back() == ' ' || text.back() == '\t')) {
    text.pop_back();
  }
  return text;
}

// Whitespace-separated numbers, each parsed strictly and required finite.
std::vector<double> ParseNumbers(const std::string& text, const std::string& file, int64_t line,
                                 const std::string& what) {
  std::vector<double> values;
  std::istringstream in(text);
  std::string token;
  while (in >> token) {
    errno = 0;
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (end != token.c_str() + token.size() || errno == ERANGE) {
      throw InputError(InputErrorKind::kMalformedRow, file, line,
                       what + ": '" + token + "' is not a number");
    }
    if (!std::isfinite(v)) {
      throw InputError(InputErrorKind::kNonFinite, file, line, what + ": '" + token + "'");
    }
    values.push_back(v);
  }
  return values;
}

// A KITTI calibration file: "key: value value ..." per line.
class CalibFile {
 public:
  explicit CalibFile(const std::string& path) : path_(path) {
    std::ifstream in(path);
    if (!in) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open");
    std::string text;
    int64_t line = 0;
    while (std::getline(in, text)) {
      ++line;
      text = TrimRight(text);
      if (text.empty()) continue;
      const size_t colon = text.find(':');
      if (colon == std::string::npos || colon == 0) {
        throw InputError(InputErrorKind::kMalformedRow, path, line,
                         "expected 'key: values', got '" + text + "'");
      }
      entries_[text.substr(0, colon)] = {line, text.substr(colon + 1)};
    }
  }

  /// The numbers of `key`, exactly `count` of them.
  std::vector<double> Numbers(const std::string& key, size_t count) const {
    const auto it = entries_.find(key);
    if (it == entries_.end()) {
      throw InputError(InputErrorKind::kMissingField, path_, 0, "no '" + key + ":' line");
    }
    std::vector<double> values = ParseNumbers(it->second.text, path_, it->second.line, key);
    if (values.size() != count) {
      throw InputError(InputErrorKind::kMalformedRow, path_, it->second.line,
                       key + " has " + std::to_string(values.size()) + " numbers, expected " +
                           std::to_string(count));
    }
    return values;
  }

  /// A rotation (9 numbers, row-major), checked and re-orthonormalised.
  Eigen::Matrix3d Rotation(const std::string& key) const {
    const std::vector<double> v = Numbers(key, 9);
    Eigen::Matrix3d R;
    R << v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8];
    if (!IsRotation(R, kCalibRotationTolerance)) {
      throw InputError(InputErrorKind::kNotRotation, path_, entries_.at(key).line,
                       key + " is not a rotation matrix (to 1e-5)");
    }
    // The nearest rotation (polar decomposition): the dataset readers
    // demand orthonormality to 1e-3 and Eigen's quaternions assume it.
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    return svd.matrixU() * svd.matrixV().transpose();
  }

  /// R and T lines as one transform.
  Pose Transform(const std::string& r_key, const std::string& t_key) const {
    Pose T = Pose::Identity();
    T.linear() = Rotation(r_key);
    const std::vector<double> t = Numbers(t_key, 3);
    T.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    return T;
  }

 private:
  struct Entry {
    int64_t line = 0;
    std::string text;
  };
  std::string path_;
  std::map<std::string, Entry> entries_;
};

}  // namespace

bool ParseKittiTimestampNs(const std::string& text, int64_t* t_ns) {
  // YYYY-MM-DD hh:mm:ss[.f{1,9}]
  if (text.size() < 19 || text[4] != '-' || text[7] != '-' || text[10] != ' ' || text[13] != ':' ||
      text[16] != ':') {
    return false;
  }
  int64_t year, month, day, hour, minute, second;
  if (!ParseFixedDigits(text, 0, 4, &year) || !ParseFixedDigits(text, 5, 2, &month) ||
      !ParseFixedDigits(text, 8, 2, &day) || !ParseFixedDigits(text, 11, 2, &hour) ||
      !ParseFixedDigits(text, 14, 2, &minute) || !ParseFixedDigits(text, 17, 2, &second)) {
    return false;
  }
  if (month < 1 || month > 12 || day < 1 || day > DaysInMonth(year, month) || hour > 23 ||
      minute > 59 || second > 59) {
    return false;
  }
  int64_t fraction_ns = 0;
  if (text.size() > 19) {
    const size_t digits = text.size() - 20;
    if (text[19] != '.' || digits < 1 || digits > 9) return false;
    if (!ParseFixedDigits(text, 20, digits, &fraction_ns)) return false;
    for (size_t i = digits; i < 9; ++i) fraction_ns *= 10;
  }
  const int64_t seconds =
      DaysFromCivil(year, month, day) * 86400 + hour * 3600 + minute * 60 + second;
  *t_ns = seconds * 1000000000 + fraction_ns;
  return true;
}

std::vector<int64_t> ReadKittiTimestamps(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open");
  std::vector<int64_t> stamps;
  std::string text;
  int64_t line = 0;
  bool saw_empty = false;
  while (std::getline(in, text)) {
    ++line;
    text = TrimRight(text);
    if (text.empty()) {
      saw_empty = true;
      continue;
    }
    if (saw_empty) {
      throw InputError(InputErrorKind::kMalformedRow, path, line - 1,
                       "empty line inside the list (frame indices would shift)");
    }
    int64_t t_ns = 0;
    if (!ParseKittiTimestampNs(text, &t_ns)) {
      throw InputError(InputErrorKind::kMalformedRow, path, line,
                       "'" + text + "' is not a time 'YYYY-MM-DD hh:mm:ss.fffffffff'");
    }
    if (!stamps.empty() && t_ns <= stamps.back()) {
      throw InputError(InputErrorKind::kUnsorted, path, line,
                       "'" + text + "' is not after the previous timestamp");
    }
    stamps.push_back(t_ns);
  }
  return stamps;
}

KittiCalibration ReadKittiCalibration(const std::string& calib_dir) {
  const CalibFile cam_to_cam(calib_dir + "/calib_cam_to_cam.txt");
  const CalibFile velo_to_cam(calib_dir + "/calib_velo_to_cam.txt");
  const CalibFile imu_to_velo(calib_dir + "/calib_imu_to_velo.txt");
  KittiCalibration calibration;
  for (int i = 0; i < 4; ++i) {
    const std::string suffix = "_0" + std::to_string(i);
    const std::vector<double> p = cam_to_cam.Numbers("P_rect" + suffix, 12);
    calibration.P_rect[i] =
        Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>>(p.data());
    const std::vector<double> s = cam_to_cam.Numbers("S_rect" + suffix, 2);
    calibration.image_size[i] =
        Eigen::Vector2i(static_cast<int>(std::lround(s[0])), static_cast<int>(std::lround(s[1])));
    const Eigen::Matrix3d K = calibration.P_rect[i].leftCols<3>();
    if (K(0, 0) <= 0 || K(1, 1) <= 0 || K(2, 2) != 1.0 || K(1, 0) != 0 || K(2, 0) != 0 ||
        K(2, 1) != 0 || calibration.image_size[i].minCoeff() <= 0) {
      throw InputError(
          InputErrorKind::kBadValue, calib_dir + "/calib_cam_to_cam.txt", 0,
          "P_rect" + suffix + " / S_rect" + suffix + " do not describe a rectified pinhole camera");
    }
  }
  calibration.T_rect0_cam0.linear() = cam_to_cam.Rotation("R_rect_00");
  calibration.T_cam0_velo = velo_to_cam.Transform("R", "T");
  calibration.T_velo_imu = imu_to_velo.Transform("R", "T");
  return calibration;
}

Pose KittiRectifiedCameraInCam0(const KittiCalibration& calibration, int index) {
  const Eigen::Matrix<double, 3, 4>& P = calibration.P_rect.at(index);
  const Eigen::Matrix3d K = P.leftCols<3>();
  // p_camx = p_rect0 + t, so T_camx_rect0 = [I | t] and T_rect0_camx = [I | -t].
  const Eigen::Vector3d t = K.inverse() * P.col(3);
  Pose T_rect0_camx = Pose::Identity();
  T_rect0_camx.translation() = -t;
  return T_rect0_camx;
}

AgentCalibration KittiAgentCalibration(const KittiCalibration& calibration, int camera_index,
                                       bool with_lidar) {
  const Eigen::Matrix<double, 3, 4>& P = calibration.P_rect.at(camera_index);
  AgentCalibration out;
  CameraParams& camera = out.camera.camera;
  camera.model = "pinhole";
  camera.width = calibration.image_size[camera_index].x();
  camera.height = calibration.image_size[camera_index].y();
  camera.fx = P(0, 0);
  camera.fy = P(1, 1);
  camera.cx = P(0, 2);
  camera.cy = P(1, 2);
  camera.distortion.clear();  // rectified images
  const Pose T_imu_velo = calibration.T_velo_imu.inverse();
  const Pose T_imu_cam0 = T_imu_velo * calibration.T_cam0_velo.inverse();
  out.camera.T_body_camera = T_imu_cam0 * calibration.T_rect0_cam0.inverse() *
                             KittiRectifiedCameraInCam0(calibration, camera_index);
  if (with_lidar) {
    LidarCalibration lidar;
    lidar.T_body_lidar = T_imu_velo;
    out.lidar = lidar;
  }
  return out;
}

OxtsPacket ReadOxtsPacket(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open");
  std::string text;
  if (!std::getline(in, text)) {
    throw InputError(InputErrorKind::kMalformedRow, path, 1, "empty file");
  }
  const std::vector<double> v = ParseNumbers(text, path, 1, "OXTS packet");
  if (v.size() != 30) {
    throw InputError(InputErrorKind::kMalformedRow, path, 1,
                     "an OXTS packet has 30 values, got " + std::to_string(v.size()));
  }
  OxtsPacket packet;
  packet.lat_deg = v[0];
  packet.lon_deg = v[1];
  packet.alt_m = v[2];
  packet.roll = v[3];
  packet.pitch = v[4];
  packet.yaw = v[5];
  if (std::abs(packet.lat_deg) >= 85.0) {
    throw InputError(InputErrorKind::kBadValue, path, 1,
                     "latitude " + std::to_string(packet.lat_deg) + " deg is out of range");
  }
  return packet;
}

PointCloud ReadKittiVelodyne(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open");
  const std::streamoff bytes = in.tellg();
  if (bytes < 0 || bytes % 16 != 0) {
    throw InputError(InputErrorKind::kMalformedRow, path, 0,
                     "size " + std::to_string(bytes) +
                         " bytes is not a multiple of 16 (float32 x y z reflectance)");
  }
  std::vector<float> raw(static_cast<size_t>(bytes) / sizeof(float));
  in.seekg(0);
  if (!in.read(reinterpret_cast<char*>(raw.data()), bytes)) {
    throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot read");
  }
  const size_t n = raw.size() / 4;
  PointCloud cloud;
  cloud.points.reserve(n);
  cloud.intensity.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const float* p = &raw[4 * i];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]) ||
        !std::isfinite(p[3])) {
      throw InputError(InputErrorKind::kNonFinite, path, 0,
                       "point " + std::to_string(i) + " has a non-finite value");
    }
    cloud.points.emplace_back(p[0], p[1], p[2]);
    cloud.intensity.push_back(p[3]);
  }
  return cloud;
}

double KittiLatToScale(double lat_deg) { return std::cos(lat_deg * M_PI / 180.0); }

Eigen::Vector2d KittiLatLonToMercator(double lat_deg, double lon_deg, double scale) {
  const double mx = scale * lon_deg * M_PI * kEarthRadiusM / 180.0;
  const double my = scale * kEarthRadiusM * std::log(std::tan((90.0 + lat_deg) * M_PI / 360.0));
  return Eigen::Vector2d(mx, my);
}

Pose OxtsToEnuPose(const OxtsPacket& packet, double scale) {
  Pose T = Pose::Identity();
  T.linear() = (Eigen::AngleAxisd(packet.yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(packet.pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(packet.roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  const Eigen::Vector2d xy = KittiLatLonToMercator(packet.lat_deg, packet.lon_deg, scale);
  T.translation() = Eigen::Vector3d(xy.x(), xy.y(), packet.alt_m);
  return T;
}

std::vector<Pose> OxtsToPoses(const std::vector<OxtsPacket>& packets, KittiWorld world) {
  std::vector<Pose> poses;
  if (packets.empty()) return poses;
  const double scale = KittiLatToScale(packets.front().lat_deg);
  const Pose T_enu_first = OxtsToEnuPose(packets.front(), scale);
  // T_wg_enu = T_enu_wg^-1 with T_enu_wg the first pose (devkit) or its
  // translation and yaw only. Translations are differenced before rotating:
  // Mercator coordinates are ~1e6 m, and the first position becomes exactly 0.
  const Eigen::Matrix3d R_wg_enu = world == KittiWorld::kFirstPose
                                       ? Eigen::Matrix3d(T_enu_first.linear().transpose())
                                       : RotZ(-packets.front().yaw);
  poses.reserve(packets.size());
  for (const OxtsPacket& packet : packets) {
    const Pose T_enu_imu = OxtsToEnuPose(packet, scale);
    Pose T_wg_imu = Pose::Identity();
    T_wg_imu.linear() = R_wg_enu * T_enu_imu.linear();
    T_wg_imu.translation() = R_wg_enu * (T_enu_imu.translation() - T_enu_first.translation());
    poses.push_back(T_wg_imu);
  }
  if (world == KittiWorld::kFirstPose) poses.front() = Pose::Identity();  // not up to rounding
  return poses;
}

}  // namespace ag
