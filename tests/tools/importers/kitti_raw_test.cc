// The KITTI raw readers and conversions on synthetic files with known
// answers (no ../shared needed): exact timestamps against libc's timegm,
// the devkit's OXTS-to-pose formula written out independently, the
// calibration chain with a known baseline, Velodyne .bin reading, and an
// import of a synthetic drive with missing frames.

#include "tools/importers/kitti_raw.h"

#include <gtest/gtest.h>

#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "common/core/error.h"
#include "common/dataset/dataset.h"
#include "tests/support/test_support.h"
#include "tools/importers/kitti_import.h"

namespace ag {
namespace {

namespace fs = std::filesystem;
using K = InputErrorKind;

void WriteText(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

/// Runs `f` and checks it throws InputError of `kind` naming `file` (and
/// `line` when >= 0).
template <class F>
void ExpectInputError(F f, K kind, const std::string& file, int64_t line = -1) {
  try {
    f();
    ADD_FAILURE() << "no InputError (expected " << ToString(kind) << " in " << file << ")";
  } catch (const InputError& e) {
    EXPECT_EQ(e.kind(), kind) << e.what();
    EXPECT_EQ(e.file(), file) << e.what();
    if (line >= 0) {
      EXPECT_EQ(e.line(), line) << e.what();
    }
  }
}

TEST(KittiTimestamp, ParsesExactlyAgainstTimegm) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> year(1971, 2100), month(1, 12), day(1, 28), hour(0, 23),
      minute(0, 59), second(0, 59), nanos(0, 999999999);
  for (int i = 0; i < 500; ++i) {
    std::tm tm{};
    tm.tm_year = year(rng) - 1900;
    tm.tm_mon = month(rng) - 1;
    tm.tm_mday = day(rng);
    tm.tm_hour = hour(rng);
    tm.tm_min = minute(rng);
    tm.tm_sec = second(rng);
    const int ns = nanos(rng);
    char text[64];
    std::snprintf(text, sizeof(text), "%04d-%02d-%02d %02d:%02d:%02d.%09d", tm.tm_year + 1900,
                  tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ns);
    const int64_t expected = static_cast<int64_t>(timegm(&tm)) * 1000000000LL + ns;
    int64_t t_ns = 0;
    ASSERT_TRUE(ParseKittiTimestampNs(text, &t_ns)) << text;
    EXPECT_EQ(t_ns, expected) << text;
  }
}

TEST(KittiTimestamp, KnownValuesAndShortFractions) {
  int64_t t = 0;
  ASSERT_TRUE(ParseKittiTimestampNs("2011-09-26 13:02:25.964389445", &t));
  EXPECT_EQ(t, 1317042145964389445LL);
  ASSERT_TRUE(ParseKittiTimestampNs("1970-01-01 00:00:00.000000001", &t));
  EXPECT_EQ(t, 1);
  ASSERT_TRUE(ParseKittiTimestampNs("1970-01-01 00:00:01.5", &t));
  EXPECT_EQ(t, 1500000000);
  ASSERT_TRUE(ParseKittiTimestampNs("2000-02-29 00:00:00", &t));  // leap year
  EXPECT_EQ(t, 951782400LL * 1000000000LL);
}

TEST(KittiTimestamp, RejectsBadText) {
  int64_t t = 0;
  for (const char* bad :
       {"", "2011-09-26", "2011-09-26 13:02:25.", "2011-09-26 13:02:25.1234567890",
        "2011-09-26T13:02:25.1", "2011-13-01 00:00:00", "2011-02-29 00:00:00",
        "2011-09-26 24:00:00", "2011-09-26 13:60:00", "2011-09-26 13:02:2x.1",
        "2011-09-26 13:02:25.1 ", "1900-02-29 00:00:00"}) {
    EXPECT_FALSE(ParseKittiTimestampNs(bad, &t)) << "'" << bad << "'";
  }
}

TEST(KittiTimestamp, FileErrorsNameTheLine) {
  test::TempDir dir;
  const std::string path = dir / "timestamps.txt";
  WriteText(path, "2011-09-26 13:02:25.1\n2011-09-26 13:02:25.2\n2011-09-26 13:02:25.2\n");
  ExpectInputError([&] { ReadKittiTimestamps(path); }, K::kUnsorted, path, 3);
  WriteText(path, "2011-09-26 13:02:25.1\r\nnot a time\r\n");
  ExpectInputError([&] { ReadKittiTimestamps(path); }, K::kMalformedRow, path, 2);
  WriteText(path, "2011-09-26 13:02:25.1\n\n2011-09-26 13:02:25.3\n");
  ExpectInputError([&] { ReadKittiTimestamps(path); }, K::kMalformedRow, path, 2);
  WriteText(path, "2011-09-26 13:02:25.1\r\n2011-09-26 13:02:25.2\r\n\r\n");
  EXPECT_EQ(ReadKittiTimestamps(path).size(), 2u);
  ExpectInputError([&] { ReadKittiTimestamps(dir / "absent.txt"); }, K::kMissingFile,
                   dir / "absent.txt", 0);
}

// The devkit (convertOxtsToPose.m, latToScale.m, latlonToMercator.m)
// written out with plain matrices.
Eigen::Matrix4d DevkitPose(const OxtsPacket& p, double lat0) {
  const double scale = std::cos(lat0 * M_PI / 180.0);
  const double er = 6378137.0;
  const double tx = scale * p.lon_deg * M_PI * er / 180.0;
  const double ty = scale * er * std::log(std::tan((90.0 + p.lat_deg) * M_PI / 360.0));
  const double rx = p.roll, ry = p.pitch, rz = p.yaw;
  Eigen::Matrix3d R_x, R_y, R_z;
  R_x << 1, 0, 0, 0, std::cos(rx), -std::sin(rx), 0, std::sin(rx), std::cos(rx);
  R_y << std::cos(ry), 0, std::sin(ry), 0, 1, 0, -std::sin(ry), 0, std::cos(ry);
  R_z << std::cos(rz), -std::sin(rz), 0, std::sin(rz), std::cos(rz), 0, 0, 0, 1;
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = R_z * R_y * R_x;
  T.topRightCorner<3, 1>() = Eigen::Vector3d(tx, ty, p.alt_m);
  return T;
}

std::vector<OxtsPacket> SomePackets() {
  return {{49.015003823272, 8.4342971002335, 116.43032836914, 0.035752, 0.00903, -2.6087069803847},
          {49.015009, 8.434311, 116.5, 0.03, 0.01, -2.5},
          {49.015100, 8.434200, 117.0, -0.02, 0.05, 3.1}};
}

TEST(KittiOxts, DevkitWorldEqualsTheDevkitFormula) {
  const std::vector<OxtsPacket> packets = SomePackets();
  const std::vector<Pose> poses = OxtsToPoses(packets, KittiWorld::kFirstPose);
  const Eigen::Matrix4d T0_inv = DevkitPose(packets[0], packets[0].lat_deg).inverse();
  ASSERT_EQ(poses.size(), packets.size());
  EXPECT_EQ(poses[0].matrix(), Eigen::Matrix4d::Identity());
  for (size_t i = 0; i < packets.size(); ++i) {
    const Eigen::Matrix4d expected = T0_inv * DevkitPose(packets[i], packets[0].lat_deg);
    // Mercator coordinates are ~1e6 m: the devkit's form loses ~1e-9 m.
    EXPECT_LT((poses[i].matrix() - expected).cwiseAbs().maxCoeff(), 1e-8) << i;
  }
}

TEST(KittiOxts, GravityWorldKeepsZUpAndRemovesOnlyPositionAndHeading) {
  const std::vector<OxtsPacket> packets = SomePackets();
  const std::vector<Pose> gravity = OxtsToPoses(packets, KittiWorld::kGravityAligned);
  const std::vector<Pose> devkit = OxtsToPoses(packets, KittiWorld::kFirstPose);
  EXPECT_EQ(gravity[0].translation(), Eigen::Vector3d::Zero());
  EXPECT_NEAR(YawOf(gravity[0].linear()), 0.0, 1e-12);
  for (size_t i = 0; i < packets.size(); ++i) {
    // World z is the ENU up axis: the IMU's tilt from it is the OXTS roll and
    // pitch, whatever the first pose was.
    const Eigen::Vector3d up_in_imu = gravity[i].linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(packets[i].pitch, Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(packets[i].roll, Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    EXPECT_LT((up_in_imu - tilt.transpose() * Eigen::Vector3d::UnitZ()).norm(), 1e-12) << i;
    // Both worlds describe the same motion: T_wg = T_wg_devkit composed
    // with one fixed transform (the first pose's roll and pitch).
    const Pose fixed = gravity[0] * devkit[0].inverse();
    EXPECT_LT((gravity[i].matrix() - (fixed * devkit[i]).matrix()).cwiseAbs().maxCoeff(), 1e-8);
  }
  // Height differences are altitude differences.
  EXPECT_NEAR(gravity[2].translation().z(), packets[2].alt_m - packets[0].alt_m, 1e-9);
}

TEST(KittiOxts, MercatorMatchesTheDevkit) {
  const double scale = KittiLatToScale(49.0);
  EXPECT_DOUBLE_EQ(scale, std::cos(49.0 * M_PI / 180.0));
  const Eigen::Vector2d xy = KittiLatLonToMercator(49.0, 8.0, scale);
  EXPECT_DOUBLE_EQ(xy.x(), scale * 8.0 * M_PI * 6378137.0 / 180.0);
  EXPECT_DOUBLE_EQ(xy.y(), scale * 6378137.0 * std::log(std::tan((90.0 + 49.0) * M_PI / 360.0)));
}

TEST(KittiOxts, PacketFileErrors) {
  test::TempDir dir;
  const std::string path = dir / "0000000000.txt";
  std::string line = "49.0 8.4 116.4 0.03 0.009 -2.6";
  for (int i = 6; i < 30; ++i) line += " 0";
  WriteText(path, line + "\n");
  const OxtsPacket packet = ReadOxtsPacket(path);
  EXPECT_EQ(packet.lat_deg, 49.0);
  EXPECT_EQ(packet.yaw, -2.6);
  WriteText(path, "49.0 8.4 116.4\n");
  ExpectInputError([&] { ReadOxtsPacket(path); }, K::kMalformedRow, path, 1);
  WriteText(path, "49.0 8.4 nan" + line.substr(std::string("49.0 8.4 116.4").size()) + "\n");
  ExpectInputError([&] { ReadOxtsPacket(path); }, K::kNonFinite, path, 1);
}

// Calibration files of a rig where every transform is known: velodyne = IMU
// shifted by (0.8, -0.3, 0.8) m; camera 0 = velodyne axes turned to OpenCV
// (x right, y down, z forward) 0.27 m ahead; no rectification rotation;
// camera 2 0.06 m left and camera 3 0.47 m right of camera 0.
constexpr double kFx = 700.0, kCx = 600.0, kCy = 170.0;
constexpr double kBaseline2 = 0.06, kBaseline3 = -0.47;  // P(0,3) / fx

std::string P(double tx_fx) {
  char text[256];
  std::snprintf(text, sizeof(text), "%.10g 0 %.10g %.10g 0 %.10g %.10g 0 0 0 1 0", kFx, kCx, tx_fx,
                kFx, kCy);
  return text;
}

void WriteCalibrationFiles(const std::string& dir,
                           const std::string& r_rect = "1 0 0 0 1 0 0 0 1") {
  std::string cam = "calib_time: 09-Jan-2012 13:57:47\ncorner_dist: 9.950000e-02\n";
  const double b[4] = {0.0, -0.54, kBaseline2, kBaseline3};
  for (int i = 0; i < 4; ++i) {
    const std::string s = "_0" + std::to_string(i);
    cam += "S_rect" + s + ": 1.242000e+03 3.750000e+02\n";
    cam += "P_rect" + s + ": " + P(b[i] * kFx) + "\n";
  }
  cam += "R_rect_00: " + r_rect + "\n";
  WriteText(dir + "/calib_cam_to_cam.txt", cam);
  // p_cam0 = R p_velo + T with R mapping velodyne x fwd / y left / z up to
  // camera x right / y down / z forward; camera 0 centre at velo (0.27, 0, 0).
  WriteText(dir + "/calib_velo_to_cam.txt",
            "calib_time: 15-Mar-2012 11:37:16\nR: 0 -1 0 0 0 -1 1 0 0\nT: 0 0 -0.27\n"
            "delta_f: 0 0\ndelta_c: 0 0\n");
  // p_velo = p_imu + T: the IMU origin is at velo (-0.8, 0.3, -0.8).
  WriteText(dir + "/calib_imu_to_velo.txt",
            "calib_time: 25-May-2012 16:47:16\nR: 1 0 0 0 1 0 0 0 1\nT: -0.8 0.3 -0.8\n");
}

TEST(KittiCalibration, CameraAndLidarInTheImuFrame) {
  test::TempDir dir;
  WriteCalibrationFiles(dir.path());
  const KittiCalibration calibration = ReadKittiCalibration(dir.path());
  EXPECT_LT((KittiRectifiedCameraInCam0(calibration, 2).translation() -
             Eigen::Vector3d(-kBaseline2, 0, 0))
                .norm(),
            1e-12);
  Eigen::Matrix3d R_imu_camera;  // camera x right = -y, y down = -z, z forward = x of the IMU
  R_imu_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const double ahead = 0.8 + 0.27;
  for (int index : {2, 3}) {
    const double b = index == 2 ? kBaseline2 : kBaseline3;
    const AgentCalibration agent = KittiAgentCalibration(calibration, index, index == 2);
    EXPECT_EQ(agent.camera.camera.model, "pinhole");
    EXPECT_EQ(agent.camera.camera.width, 1242);
    EXPECT_EQ(agent.camera.camera.height, 375);
    EXPECT_EQ(agent.camera.camera.fx, kFx);
    EXPECT_EQ(agent.camera.camera.cx, kCx);
    EXPECT_EQ(agent.camera.camera.cy, kCy);
    EXPECT_TRUE(agent.camera.camera.distortion.empty());
    EXPECT_LT((agent.camera.T_body_camera.linear() - R_imu_camera).cwiseAbs().maxCoeff(), 1e-12);
    // A camera with P(0,3) = fx * b sits b metres to the left (+y of the IMU).
    const Eigen::Vector3d expected(ahead, -0.3 + b, 0.8);
    EXPECT_LT((agent.camera.T_body_camera.translation() - expected).norm(), 1e-12) << index;
    EXPECT_EQ(agent.lidar.has_value(), index == 2);
  }
  const AgentCalibration ground = KittiAgentCalibration(calibration, 2, true);
  EXPECT_LT((ground.lidar->T_body_lidar.translation() - Eigen::Vector3d(0.8, -0.3, 0.8)).norm(),
            1e-12);
}

TEST(KittiCalibration, RectificationRotationIsUndone) {
  // R_rect_00 rotates unrectified camera-0 points into the rectified frame:
  // the rectified camera's axes are R_rect_00^T in unrectified coordinates.
  test::TempDir dir;
  const Eigen::Matrix3d R_rect =
      Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  char text[256];
  std::snprintf(text, sizeof(text), "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g",
                R_rect(0, 0), R_rect(0, 1), R_rect(0, 2), R_rect(1, 0), R_rect(1, 1), R_rect(1, 2),
                R_rect(2, 0), R_rect(2, 1), R_rect(2, 2));
  WriteCalibrationFiles(dir.path(), text);
  const KittiCalibration calibration = ReadKittiCalibration(dir.path());
  const AgentCalibration agent = KittiAgentCalibration(calibration, 2, true);
  const Pose T_cam0_imu = calibration.T_cam0_velo * calibration.T_velo_imu;
  const Eigen::Matrix3d R_cam0_rect = (T_cam0_imu.linear() * agent.camera.T_body_camera.linear());
  EXPECT_LT((R_cam0_rect - R_rect.transpose()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(KittiCalibration, FileErrorsNameFileAndLine) {
  test::TempDir dir;
  WriteCalibrationFiles(dir.path(), "1 0 0 0 1 0 0 0 2");
  ExpectInputError([&] { ReadKittiCalibration(dir.path()); }, K::kNotRotation,
                   dir / "calib_cam_to_cam.txt", 11);
  WriteCalibrationFiles(dir.path(), "1 0 0 0 1 0 0 0");
  ExpectInputError([&] { ReadKittiCalibration(dir.path()); }, K::kMalformedRow,
                   dir / "calib_cam_to_cam.txt", 11);
  WriteCalibrationFiles(dir.path());
  WriteText(dir / "calib_imu_to_velo.txt", "R: 1 0 0 0 1 0 0 0 1\n");
  ExpectInputError([&] { ReadKittiCalibration(dir.path()); }, K::kMissingField,
                   dir / "calib_imu_to_velo.txt", 0);
  fs::remove(dir / "calib_velo_to_cam.txt");
  ExpectInputError([&] { ReadKittiCalibration(dir.path()); }, K::kMissingFile,
                   dir / "calib_velo_to_cam.txt", 0);
}

void WriteVelodyne(const std::string& path, const std::vector<float>& values) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(values.data()),
            static_cast<std::streamsize>(values.size() * sizeof(float)));
}

TEST(KittiVelodyne, ReadsPointsAndReflectance) {
  test::TempDir dir;
  const std::string path = dir / "0000000000.bin";
  WriteVelodyne(path, {1.5f, -2.25f, 0.125f, 0.5f, 10.f, 20.f, -1.f, 0.f});
  const PointCloud cloud = ReadKittiVelodyne(path);
  ASSERT_EQ(cloud.points.size(), 2u);
  EXPECT_EQ(cloud.points[0], Eigen::Vector3f(1.5f, -2.25f, 0.125f));
  EXPECT_EQ(cloud.points[1], Eigen::Vector3f(10.f, 20.f, -1.f));
  EXPECT_EQ(cloud.intensity, (std::vector<float>{0.5f, 0.f}));
  WriteVelodyne(path, {1.f, 2.f, 3.f});
  ExpectInputError([&] { ReadKittiVelodyne(path); }, K::kMalformedRow, path, 0);
  WriteVelodyne(path, {1.f, 2.f, 3.f, 0.f, 1.f, NAN, 3.f, 0.f});
  ExpectInputError([&] { ReadKittiVelodyne(path); }, K::kNonFinite, path, 0);
}

/// A synthetic drive: timestamps.txt list `listed` frames, data files
/// exist for `present` only.
std::string WriteSyntheticDrive(const std::string& root, int listed,
                                const std::vector<int>& present) {
  const std::string day = root + "/2011_01_01";
  std::string drive = day + "/2011_01_01_drive_0007_sync";
  WriteCalibrationFiles(day);
  std::string oxts_tail;
  for (int i = 6; i < 30; ++i) oxts_tail += " 0";
  for (const std::string sensor : {"image_02", "image_03", "velodyne_points", "oxts"}) {
    std::string stamps;
    for (int i = 0; i < listed; ++i) {
      char text[64];
      // Sensors 1-3 ms apart, frames 100 ms apart.
      const int ms = 100 * i + (sensor == "oxts" ? 3 : sensor == "velodyne_points" ? 1 : 2);
      std::snprintf(text, sizeof(text), "2011-01-01 10:00:%02d.%03d000000\n", ms / 1000, ms % 1000);
      stamps += text;
    }
    WriteText(drive + "/" + sensor + "/timestamps.txt", stamps);
    fs::create_directories(drive + "/" + sensor + "/data");
    for (int i : present) {
      char name[32];
      std::snprintf(name, sizeof(name), "%010d", i);
      const std::string base = drive + "/" + sensor + "/data/" + name;
      if (sensor == "oxts") {
        char text[128];
        std::snprintf(text, sizeof(text), "49.0 %.9f 100 0 0 0.5", 8.0 + 1e-5 * i);
        WriteText(base + ".txt", text + oxts_tail + "\n");
      } else if (sensor == "velodyne_points") {
        WriteVelodyne(base + ".bin", {5.f, 0.f, 0.f, 0.2f, 6.f, 1.f, -1.f, 0.3f});
      } else {
        cv::imwrite(base + ".png", cv::Mat(375, 1242, CV_8UC3, cv::Scalar(i, 2 * i, 3 * i)));
      }
    }
  }
  return drive;
}

TEST(KittiImportSynthetic, ImportsTheFramesThatExistAndCountsTheRest) {
  test::TempDir dir;
  WriteSyntheticDrive(dir / "raw", 6, {0, 2, 3});
  KittiImportOptions options;
  options.input = dir / "raw";  // the drive is found two levels below
  options.out_dir = dir / "out";
  options.pseudo_air = "air";
  options.air_offset = {1, 2, 3, 90};
  const KittiImportSummary summary = ImportKittiRaw(options);
  ASSERT_EQ(summary.sensors.size(), 4u);
  for (const KittiSensorCount& s : summary.sensors) {
    EXPECT_EQ(s.listed, 6u) << s.sensor;
    EXPECT_EQ(s.imported, 3u) << s.sensor;
    EXPECT_EQ(s.Skipped(), 3u) << s.sensor;
  }
  // Frame 0's image and scan come 1-2 ms before its OXTS packet.
  EXPECT_EQ(summary.frames_outside_odometry, 3u);
  const Dataset dataset = ReadDataset(dir / "out");
  ASSERT_EQ(dataset.ground.images.size(), 3u);
  EXPECT_EQ(dataset.ground.images[1].t_ns % 1000000000LL, 202000000);  // frame 2, image_02
  EXPECT_EQ(dataset.ground.scans[2].t_ns % 1000000000LL, 301000000);   // frame 3, velodyne
  EXPECT_EQ(dataset.ground.odometry[1].t_ns % 1000000000LL, 203000000);
  const cv::Mat image = LoadImage(dataset.ground.images[2]);
  EXPECT_EQ(image.at<cv::Vec3b>(0, 0), cv::Vec3b(3, 6, 9));  // frame 3, byte copy
  EXPECT_EQ(dataset.name, "2011_01_01_drive_0007_sync");
  EXPECT_EQ(dataset.groundtruth->T_wa_wg.at("air").matrix(),
            MakePose4Dof(1, 2, 3, M_PI / 2).matrix());
}

TEST(KittiImportSynthetic, RefusesADataFileWithoutTimestamp) {
  test::TempDir dir;
  const std::string drive = WriteSyntheticDrive(dir / "raw", 3, {0, 1});
  cv::imwrite(drive + "/image_02/data/0000000005.png", cv::Mat(375, 1242, CV_8UC3));
  KittiImportOptions options;
  options.input = drive;
  options.out_dir = dir / "out";
  ExpectInputError([&] { ImportKittiRaw(options); }, K::kBadValue,
                   drive + "/image_02/data/0000000005.png", 0);
}

TEST(KittiImportSynthetic, RejectsBadOptions) {
  KittiImportOptions options;
  options.input = "x";
  options.out_dir = "y";
  options.camera = "image_2";
  EXPECT_THROW(options.Check(), OptionError);
  options.camera = "image_02";
  options.world = "enu";
  EXPECT_THROW(options.Check(), OptionError);
  options.world = "gravity";
  options.pseudo_air = "Air";
  EXPECT_THROW(options.Check(), OptionError);
  options.pseudo_air = "air";
  options.air_camera = "image_02";
  EXPECT_THROW(options.Check(), OptionError);
  options.air_camera = "image_03";
  options.air_offset = {1, 2, 3};
  EXPECT_THROW(options.Check(), OptionError);
  options.air_offset = {1, 2, 3, 4};
  EXPECT_NO_THROW(options.Check());
}

}  // namespace
}  // namespace ag
