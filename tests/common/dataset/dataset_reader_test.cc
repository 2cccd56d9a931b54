// ReadDataset on a hand-written dataset, and one test per malformed input of
// the spec's Errors section (and the extra cases: unknown keys, agent names,
// missing files), each checking the error kind, the file and the line.

#include <gtest/gtest.h>

#include <filesystem>

#include "common/dataset/dataset.h"
#include "tests/common/dataset/dataset_test_util.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

namespace fs = std::filesystem;
using test::ExpectInputError;
using test::ReplaceOnce;
using test::WriteText;
using K = InputErrorKind;

class DatasetReaderTest : public ::testing::Test {
 protected:
  void SetUp() override { test::WriteFixtureDataset(dir()); }

  std::string dir() const { return tmp_.path() + "/ds"; }
  std::string Path(const std::string& relative) const { return dir() + "/" + relative; }

  // Replaces one occurrence of `from` by `to` in a fixture file.
  void Edit(const std::string& relative, const std::string& from, const std::string& to) {
    WriteText(Path(relative), ReplaceOnce(test::ReadText(Path(relative)), from, to));
  }

  void ExpectError(K kind, const std::string& relative_file, int64_t line,
                   const std::string& fragment = "") {
    ExpectInputError([&] { ReadDataset(dir()); }, kind, Path(relative_file), line, fragment);
  }

  test::TempDir tmp_;
};

TEST_F(DatasetReaderTest, HandWrittenDatasetReads) {
  const Dataset ds = ReadDataset(dir());
  EXPECT_EQ(ds.format_version, 1);
  EXPECT_EQ(ds.name, "fixture");
  EXPECT_EQ(ds.description, "a dataset written by hand");
  // Ground calibration exactly as written.
  const AgentCalibration& g = ds.ground.calibration;
  EXPECT_EQ(g.camera.camera.model, "pinhole");
  EXPECT_EQ(g.camera.camera.width, 64);
  EXPECT_EQ(g.camera.camera.height, 48);
  EXPECT_EQ(g.camera.camera.fx, 50.0);
  EXPECT_EQ(g.camera.camera.fy, 51.0);
  EXPECT_EQ(g.camera.camera.cx, 32.0);
  EXPECT_EQ(g.camera.camera.cy, 24.0);
  EXPECT_EQ(g.camera.camera.distortion, (std::vector<double>{-0.1, 0.01, 0.001, -0.002}));
  Eigen::Matrix4d T_body_camera;
  T_body_camera << 0, 0, 1, 0.1, -1, 0, 0, 0, 0, -1, 0, 0.2, 0, 0, 0, 1;
  EXPECT_EQ(g.camera.T_body_camera.matrix(), T_body_camera);
  EXPECT_EQ(g.camera.time_offset_s, 0.004);
  ASSERT_TRUE(g.lidar.has_value());
  EXPECT_EQ(g.lidar->T_body_lidar.translation(), Eigen::Vector3d(0, 0, 0.3));
  EXPECT_EQ(g.lidar->T_body_lidar.linear(), Eigen::Matrix3d::Identity());
  EXPECT_EQ(g.lidar->time_offset_s, -0.01);
  // Frames.
  ASSERT_EQ(ds.ground.images.size(), 2u);
  EXPECT_EQ(ds.ground.images[1].t_ns, 1100000000);
  EXPECT_EQ(ds.ground.images[1].filename, "1100000000.png");
  EXPECT_EQ(ds.ground.images[1].path, Path("ground/images/1100000000.png"));
  ASSERT_EQ(ds.ground.scans.size(), 2u);
  EXPECT_EQ(ds.ground.scans[0].path, Path("ground/scans/1000000000.pcd"));
  ASSERT_EQ(ds.ground.odometry.size(), 3u);
  EXPECT_EQ(ds.ground.odometry[2].t_ns, 1200000000);
  EXPECT_NEAR(YawOf(ds.ground.odometry[2].T.linear()), 0.1, 1e-10);
  EXPECT_TRUE(ds.ground.groundtruth.empty());
  EXPECT_EQ(ds.ground.dir, Path("ground"));
  // Air agent: fisheye, no lidar, defaults for the optional time offset.
  ASSERT_EQ(ds.air.size(), 1u);
  const AgentData& uav = ds.air.at("uav1");
  EXPECT_EQ(uav.name, "uav1");
  EXPECT_EQ(uav.dir, Path("air/uav1"));
  EXPECT_EQ(uav.calibration.camera.camera.model, "equidistant");
  EXPECT_EQ(uav.calibration.camera.time_offset_s, 0.0);
  EXPECT_FALSE(uav.calibration.lidar.has_value());
  EXPECT_TRUE(uav.scans.empty());
  // groundtruth.yaml, flow-style maps included.
  ASSERT_TRUE(ds.groundtruth.has_value());
  const Pose& T_wa_wg = ds.groundtruth->T_wa_wg.at("uav1");
  EXPECT_NEAR(YawOf(T_wa_wg.linear()), M_PI / 2, 1e-15);
  EXPECT_EQ(T_wa_wg.translation(), Eigen::Vector3d(5, -2, 0.5));
  ASSERT_TRUE(ds.groundtruth->ground_true_camera.has_value());
  EXPECT_EQ(ds.groundtruth->ground_true_camera->T_body_camera.matrix(), T_body_camera);
  EXPECT_EQ(ds.groundtruth->ground_true_camera->time_offset_s, 0.005);
  EXPECT_FALSE(ds.groundtruth->ground_true_lidar.has_value());
  EXPECT_EQ(ds.groundtruth->air_true_camera.at("uav1").time_offset_s, -0.002);
  EXPECT_EQ(ds.groundtruth->air_true_camera.at("uav1").T_body_camera.translation().x(), 0.01);
  // Pixels load lazily.
  const cv::Mat image = LoadImage(uav.images[0], cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(image.cols, 64);
  EXPECT_EQ(image.at<uint8_t>(10, 10), 7);
}

TEST_F(DatasetReaderTest, OptionalFilesMayBeAbsent) {
  fs::remove(Path("groundtruth.yaml"));
  Dataset ds = ReadDataset(dir());
  EXPECT_FALSE(ds.groundtruth.has_value());
  EXPECT_TRUE(ds.air.at("uav1").groundtruth.empty());
  // groundtruth.tum when present is read.
  WriteText(Path("air/uav1/groundtruth.tum"), test::kOdometryTum);
  ds = ReadDataset(dir());
  EXPECT_EQ(ds.air.at("uav1").groundtruth.size(), 3u);
  // No air/ at all: a ground-only dataset.
  fs::remove_all(Path("air"));
  ds = ReadDataset(dir());
  EXPECT_TRUE(ds.air.empty());
  EXPECT_EQ(ds.ground.images.size(), 2u);
  // description is free text and optional.
  WriteText(Path("dataset.yaml"), "format_version: 1\nname: x\n");
  EXPECT_EQ(ReadDataset(dir()).description, "");
}

TEST_F(DatasetReaderTest, HiddenEntriesOfAirAreIgnored) {
  WriteText(Path("air/.DS_Store"), "x");
  EXPECT_EQ(ReadDataset(dir()).air.size(), 1u);
}

TEST_F(DatasetReaderTest, CsvToleratesSpacesAfterCommasAndCrlf) {
  WriteText(Path("ground/images.csv"),
            "#timestamp [ns],filename\r\n"
            "1000000000, 1000000000.png\r\n"
            "\r\n"
            " 1100000000 ,\t1100000000.png  \r\n");
  const Dataset ds = ReadDataset(dir());
  ASSERT_EQ(ds.ground.images.size(), 2u);
  EXPECT_EQ(ds.ground.images[0].filename, "1000000000.png");
  EXPECT_EQ(ds.ground.images[1].t_ns, 1100000000);
  EXPECT_EQ(ds.ground.images[1].filename, "1100000000.png");
}

// --- Missing files -----------------------------------------------------------

TEST_F(DatasetReaderTest, MissingDatasetFolder) {
  ExpectInputError([&] { ReadDataset(dir() + "_absent"); }, K::kMissingFile, dir() + "_absent", 0);
}

TEST_F(DatasetReaderTest, MissingDatasetYaml) {
  fs::remove(Path("dataset.yaml"));
  ExpectError(K::kMissingFile, "dataset.yaml", 0);
}

TEST_F(DatasetReaderTest, MissingGroundFolder) {
  fs::remove_all(Path("ground"));
  ExpectError(K::kMissingFile, "ground", 0, "ground agent");
}

TEST_F(DatasetReaderTest, MissingCalibration) {
  fs::remove(Path("air/uav1/calibration.yaml"));
  ExpectError(K::kMissingFile, "air/uav1/calibration.yaml", 0);
}

TEST_F(DatasetReaderTest, MissingImagesCsv) {
  fs::remove(Path("ground/images.csv"));
  ExpectError(K::kMissingFile, "ground/images.csv", 0);
}

TEST_F(DatasetReaderTest, MissingImagesFolder) {
  fs::remove_all(Path("air/uav1/images"));
  ExpectError(K::kMissingFile, "air/uav1/images", 0);
}

TEST_F(DatasetReaderTest, MissingScansCsv) {
  fs::remove(Path("ground/scans.csv"));
  ExpectError(K::kMissingFile, "ground/scans.csv", 0);
}

TEST_F(DatasetReaderTest, MissingOdometry) {
  fs::remove(Path("air/uav1/odometry.tum"));
  ExpectError(K::kMissingFile, "air/uav1/odometry.tum", 0);
}

TEST_F(DatasetReaderTest, CsvNamesAFileThatDoesNotExist) {
  Edit("ground/images.csv", "1100000000,1100000000.png", "1100000000,1100000001.png");
  ExpectError(K::kMissingFile, "ground/images.csv", 3, "1100000001.png");
}

TEST_F(DatasetReaderTest, ScanListedButAbsent) {
  fs::remove(Path("ground/scans/1000000000.pcd"));
  ExpectError(K::kMissingFile, "ground/scans.csv", 2, "1000000000.pcd");
}

// --- Malformed rows ----------------------------------------------------------

TEST_F(DatasetReaderTest, CsvRowWithOneField) {
  Edit("ground/images.csv", "1100000000,1100000000.png", "1100000000");
  ExpectError(K::kMalformedRow, "ground/images.csv", 3, "got 1");
}

TEST_F(DatasetReaderTest, CsvRowWithThreeFields) {
  Edit("air/uav1/images.csv", "1000000000,1000000000.png", "1000000000,1000000000.png,7");
  ExpectError(K::kMalformedRow, "air/uav1/images.csv", 2, "got 3");
}

TEST_F(DatasetReaderTest, CsvTimestampNotAnInteger) {
  Edit("ground/scans.csv", "1100000000,", "1.1e9,");
  ExpectError(K::kMalformedRow, "ground/scans.csv", 3, "1.1e9");
}

TEST_F(DatasetReaderTest, CsvTimestampOverflows) {
  Edit("ground/images.csv", "1100000000,", "99999999999999999999,");
  ExpectError(K::kMalformedRow, "ground/images.csv", 3);
}

TEST_F(DatasetReaderTest, CsvEmptyFilename) {
  Edit("ground/images.csv", "1100000000,1100000000.png", "1100000000, ");
  ExpectError(K::kMalformedRow, "ground/images.csv", 3, "empty filename");
}

TEST_F(DatasetReaderTest, TumMalformedRow) {
  Edit("ground/odometry.tum", "1.100000000 0.1 0 0 0 0 0 1", "1.100000000 0.1 0 0 0 0 1");
  ExpectError(K::kMalformedRow, "ground/odometry.tum", 3, "expected 8 fields");
}

TEST_F(DatasetReaderTest, TumUnparsableNumber) {
  Edit("air/uav1/odometry.tum", "1.100000000 0.1", "1.100000000 0.1x");
  ExpectError(K::kMalformedRow, "air/uav1/odometry.tum", 3, "0.1x");
}

TEST_F(DatasetReaderTest, OptionalGroundTruthTumIsStillValidated) {
  WriteText(Path("ground/groundtruth.tum"), "1.0 0 0 0 0 0 0 1\n2.0 0 0\n");
  ExpectError(K::kMalformedRow, "ground/groundtruth.tum", 2);
}

TEST_F(DatasetReaderTest, YamlSyntaxError) {
  Edit("ground/calibration.yaml", "  intrinsics: [50.0, 51.0, 32.0, 24.0]\n",
       "  intrinsics: [50.0, 51.0, 32.0, 24.0]]\n");
  ExpectError(K::kMalformedRow, "ground/calibration.yaml", 5);
}

TEST_F(DatasetReaderTest, YamlIntrinsicsNotANumber) {
  Edit("ground/calibration.yaml", "[50.0, 51.0,", "[50.0, abc,");
  ExpectError(K::kMalformedRow, "ground/calibration.yaml", 5, "camera.intrinsics[1]");
}

TEST_F(DatasetReaderTest, YamlIntrinsicsWrongCount) {
  Edit("ground/calibration.yaml", "[50.0, 51.0, 32.0, 24.0]", "[50.0, 51.0, 32.0]");
  ExpectError(K::kMalformedRow, "ground/calibration.yaml", 5, "needs 4 numbers, got 3");
}

TEST_F(DatasetReaderTest, YamlWidthNotAnInteger) {
  Edit("ground/calibration.yaml", "width: 64", "width: 64.5");
  ExpectError(K::kMalformedRow, "ground/calibration.yaml", 3, "camera.width");
}

TEST_F(DatasetReaderTest, YamlMatrixWithThreeRows) {
  Edit("ground/calibration.yaml", ", [0, -1, 0, 0.2], [0, 0, 0, 1]]", ", [0, -1, 0, 0.2]]");
  ExpectError(K::kMalformedRow, "ground/calibration.yaml", 7, "got 3 rows");
}

TEST_F(DatasetReaderTest, YamlMatrixRowWithThreeNumbers) {
  Edit("ground/calibration.yaml", "    - [0, 1, 0, 0]\n", "    - [0, 1, 0]\n");
  ExpectError(K::kMalformedRow, "ground/calibration.yaml", 12, "row 1");
}

TEST_F(DatasetReaderTest, YamlDuplicateKey) {
  Edit("ground/calibration.yaml", "  height: 48\n", "  height: 48\n  width: 64\n");
  ExpectError(K::kMalformedRow, "ground/calibration.yaml", 5, "duplicate key 'camera.width'");
}

// --- Non-finite numbers --------------------------------------------------------

TEST_F(DatasetReaderTest, TumNonFinite) {
  Edit("ground/odometry.tum", "1.100000000 0.1 0 0", "1.100000000 0.1 nan 0");
  ExpectError(K::kNonFinite, "ground/odometry.tum", 3);
}

TEST_F(DatasetReaderTest, YamlNonFiniteYamlSpelling) {
  Edit("ground/calibration.yaml", "[50.0, 51.0, 32.0, 24.0]", "[50.0, 51.0, .nan, 24.0]");
  ExpectError(K::kNonFinite, "ground/calibration.yaml", 5, "camera.intrinsics[2]");
}

TEST_F(DatasetReaderTest, YamlNonFiniteCSpelling) {
  Edit("ground/calibration.yaml", "time_offset_s: 0.004", "time_offset_s: inf");
  ExpectError(K::kNonFinite, "ground/calibration.yaml", 8, "camera.time_offset_s");
}

TEST_F(DatasetReaderTest, YamlNonFiniteInMatrix) {
  Edit("ground/calibration.yaml", "    - [0, 0, 1, 0.3]\n", "    - [0, 0, 1, -.inf]\n");
  ExpectError(K::kNonFinite, "ground/calibration.yaml", 13, "lidar.T_body_lidar[2][3]");
}

TEST_F(DatasetReaderTest, GroundTruthNonFinite) {
  Edit("groundtruth.yaml", "[0, 0, 1, 0.5]", "[0, 0, 1, NaN]");
  ExpectError(K::kNonFinite, "groundtruth.yaml", 2, "T_wa_wg.uav1");
}

// --- Non-orthonormal rotations -------------------------------------------------

TEST_F(DatasetReaderTest, TumQuaternionNotUnit) {
  Edit("air/uav1/odometry.tum", "1.100000000 0.1 0 0 0 0 0 1", "1.100000000 0.1 0 0 0 0 0 1.1");
  ExpectError(K::kNotRotation, "air/uav1/odometry.tum", 3);
}

TEST_F(DatasetReaderTest, YamlRotationBlockNotOrthonormal) {
  Edit("ground/calibration.yaml", "[[0, 0, 1, 0.1], [-1, 0, 0, 0]",
       "[[0, 0, 1, 0.1], [-1, 0.1, 0, 0]");
  ExpectError(K::kNotRotation, "ground/calibration.yaml", 7, "camera.T_body_camera");
}

TEST_F(DatasetReaderTest, YamlRotationBlockIsAReflection) {
  Edit("ground/calibration.yaml", "    - [0, 0, 1, 0.3]\n", "    - [0, 0, -1, 0.3]\n");
  ExpectError(K::kNotRotation, "ground/calibration.yaml", 11, "lidar.T_body_lidar");
}

TEST_F(DatasetReaderTest, YamlLastRowNotHomogeneous) {
  Edit("ground/calibration.yaml", "    - [0, 0, 0, 1]\n", "    - [0, 0, 0.5, 1]\n");
  ExpectError(K::kNotRotation, "ground/calibration.yaml", 14, "last row must be 0 0 0 1");
}

TEST_F(DatasetReaderTest, GroundTruthRotationNotOrthonormal) {
  Edit("groundtruth.yaml", "[[0, -1, 0, 5], [1, 0, 0, -2]", "[[0, -1, 0, 5], [2, 0, 0, -2]");
  ExpectError(K::kNotRotation, "groundtruth.yaml", 2, "T_wa_wg.uav1");
}

TEST_F(DatasetReaderTest, RoundedRotationsAreAcceptedAndMadeExact) {
  // A rotation about z by 30 degrees written with 4 decimals.
  Edit("groundtruth.yaml", "[[0, -1, 0, 5], [1, 0, 0, -2]",
       "[[0.8660, -0.5000, 0, 5], [0.5000, 0.8660, 0, -2]");
  const Dataset ds = ReadDataset(dir());
  const Eigen::Matrix3d R = ds.groundtruth->T_wa_wg.at("uav1").linear();
  EXPECT_TRUE(IsRotation(R, 1e-14));
  EXPECT_NEAR(YawOf(R), M_PI / 6, 1e-4);
}

// --- Unsorted timestamps -------------------------------------------------------

TEST_F(DatasetReaderTest, CsvUnsorted) {
  WriteText(Path("ground/images.csv"),
            "#timestamp [ns],filename\n1100000000,1100000000.png\n1000000000,1000000000.png\n");
  ExpectError(K::kUnsorted, "ground/images.csv", 3, "not after the previous one");
}

TEST_F(DatasetReaderTest, CsvDuplicateTimestamp) {
  Edit("air/uav1/images.csv", "1100000000,1100000000.png", "1000000000,1100000000.png");
  ExpectError(K::kUnsorted, "air/uav1/images.csv", 3);
}

TEST_F(DatasetReaderTest, TumUnsorted) {
  Edit("ground/odometry.tum", "1.200000000 0.2", "1.050000000 0.2");
  ExpectError(K::kUnsorted, "ground/odometry.tum", 4);
}

// --- Unknown keys, bad values, agent names ---------------------------------------

TEST_F(DatasetReaderTest, MisspeltCalibrationKeyIsRejected) {
  Edit("ground/calibration.yaml", "  distortion:", "  distorsion:");
  ExpectError(K::kUnknownKey, "ground/calibration.yaml", 6, "camera.distorsion");
}

TEST_F(DatasetReaderTest, UnknownTopLevelCalibrationKey) {
  WriteText(Path("air/uav1/calibration.yaml"), std::string(test::kAirCalibration) + "imu: {}\n");
  ExpectError(K::kUnknownKey, "air/uav1/calibration.yaml", 9, "'imu'");
}

TEST_F(DatasetReaderTest, MisspeltLidarKey) {
  Edit("ground/calibration.yaml", "  time_offset_s: -0.01", "  time_ofset_s: -0.01");
  ExpectError(K::kUnknownKey, "ground/calibration.yaml", 15, "lidar.time_ofset_s");
}

TEST_F(DatasetReaderTest, MissingRequiredCalibrationKey) {
  Edit("ground/calibration.yaml", "  intrinsics: [50.0, 51.0, 32.0, 24.0]\n", "");
  ExpectError(K::kMissingField, "ground/calibration.yaml", 2, "camera.intrinsics");
}

TEST_F(DatasetReaderTest, GroundCalibrationWithoutLidar) {
  WriteText(Path("ground/calibration.yaml"), test::kAirCalibration);
  ExpectError(K::kMissingField, "ground/calibration.yaml", 0, "lidar");
}

TEST_F(DatasetReaderTest, EmptyCalibration) {
  WriteText(Path("ground/calibration.yaml"), "# nothing\n");
  ExpectError(K::kMissingField, "ground/calibration.yaml", 0, "empty");
}

TEST_F(DatasetReaderTest, WrongDistortionCountForModel) {
  Edit("air/uav1/calibration.yaml", "[0.01, -0.002, 0.0003, 0]", "[0.01, -0.002, 0.0003, 0, 0]");
  ExpectError(K::kBadValue, "air/uav1/calibration.yaml", 7,
              "distortion equidistant needs 4 values, got 5");
}

TEST_F(DatasetReaderTest, WrongDistortionCountForRadtan) {
  Edit("ground/calibration.yaml", "[-0.1, 0.01, 0.001, -0.002]", "[-0.1, 0.01, 0.001]");
  ExpectError(K::kBadValue, "ground/calibration.yaml", 6, "got 3");
}

TEST_F(DatasetReaderTest, UnknownCameraModel) {
  Edit("ground/calibration.yaml", "model: pinhole", "model: radtan");
  ExpectError(K::kBadValue, "ground/calibration.yaml", 2, "camera.model");
}

TEST_F(DatasetReaderTest, NonPositiveFocalLength) {
  Edit("ground/calibration.yaml", "[50.0, 51.0,", "[-50.0, 51.0,");
  ExpectError(K::kBadValue, "ground/calibration.yaml", 5, "camera.intrinsics");
}

TEST_F(DatasetReaderTest, NonPositiveImageSize) {
  Edit("ground/calibration.yaml", "height: 48", "height: 0");
  ExpectError(K::kBadValue, "ground/calibration.yaml", 4, "camera.height");
}

TEST_F(DatasetReaderTest, BadAgentFolderName) {
  fs::rename(Path("air/uav1"), Path("air/UAV-1"));
  ExpectError(K::kBadValue, "air/UAV-1", 0, "[a-z0-9_]+");
}

TEST_F(DatasetReaderTest, StrayFileInAir) {
  WriteText(Path("air/notes.txt"), "hello");
  ExpectError(K::kBadValue, "air/notes.txt", 0, "not a folder");
}

TEST_F(DatasetReaderTest, GroundTruthNamesAnUnknownAgent) {
  Edit("groundtruth.yaml", "  uav1: [[0, -1", "  uav2: [[0, -1");
  ExpectError(K::kBadValue, "groundtruth.yaml", 2, "no air agent 'uav2'");
}

TEST_F(DatasetReaderTest, GroundTruthBadAgentName) {
  Edit("groundtruth.yaml", "  air: {uav1:", "  air: {Uav1:");
  ExpectError(K::kBadValue, "groundtruth.yaml", 5, "true_calibration.air.Uav1");
}

TEST_F(DatasetReaderTest, GroundTruthMisspeltKey) {
  Edit("groundtruth.yaml", "T_wa_wg:", "T_wg_wa:");
  ExpectError(K::kUnknownKey, "groundtruth.yaml", 1, "T_wg_wa");
}

TEST_F(DatasetReaderTest, GroundTruthMisspeltNestedKey) {
  Edit("groundtruth.yaml", " camera_time_offset_s: 0.005}", " camera_time_offset: 0.005}");
  ExpectError(K::kUnknownKey, "groundtruth.yaml", 4, "true_calibration.ground.camera_time_offset");
}

TEST_F(DatasetReaderTest, UnsupportedFormatVersion) {
  WriteText(Path("dataset.yaml"), "format_version: 2\nname: x\n");
  ExpectError(K::kBadValue, "dataset.yaml", 1, "format_version 2");
}

TEST_F(DatasetReaderTest, MisspeltDatasetKey) {
  WriteText(Path("dataset.yaml"), "format_version: 1\nname: x\ndescripton: y\n");
  ExpectError(K::kUnknownKey, "dataset.yaml", 3, "descripton");
}

TEST_F(DatasetReaderTest, DatasetYamlWithoutName) {
  WriteText(Path("dataset.yaml"), "format_version: 1\n");
  ExpectError(K::kMissingField, "dataset.yaml", 0, "'name'");
}

TEST(DatasetNamesTest, AgentNames) {
  EXPECT_TRUE(IsValidAgentName("uav1"));
  EXPECT_TRUE(IsValidAgentName("a_b_9"));
  EXPECT_TRUE(IsValidAgentName("0"));
  EXPECT_FALSE(IsValidAgentName(""));
  EXPECT_FALSE(IsValidAgentName("UAV1"));
  EXPECT_FALSE(IsValidAgentName("uav-1"));
  EXPECT_FALSE(IsValidAgentName("uav 1"));
  EXPECT_FALSE(IsValidAgentName("../x"));
  EXPECT_EQ(AgentDir("/d", "ground"), "/d/ground");
  EXPECT_EQ(AgentDir("/d", "uav1"), "/d/air/uav1");
  EXPECT_EQ(AgentDir("/d/", "uav1"), "/d/air/uav1");
}

TEST(LoadImageTest, MissingCorruptAndDeepImagesAreRefused) {
  test::TempDir dir;
  SensorFrame frame;
  frame.path = dir / "absent.png";
  ExpectInputError([&] { LoadImage(frame); }, K::kMissingFile, frame.path, 0);
  frame.path = dir / "corrupt.png";
  WriteText(frame.path, "not a png");
  ExpectInputError([&] { LoadImage(frame); }, K::kMissingFile, frame.path, 0);
  frame.path = dir / "deep.png";
  cv::imwrite(frame.path, cv::Mat(4, 4, CV_16UC1, cv::Scalar(1000)));
  ExpectInputError([&] { LoadImage(frame); }, K::kBadValue, frame.path, 0, "8-bit");
}

}  // namespace
}  // namespace ag
