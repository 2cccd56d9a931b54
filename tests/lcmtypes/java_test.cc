// The Java side of the schema, which lcm-spy needs to decode our messages:
// ag_lcmtypes.jar holds every message class, lcm-spy's own type database finds
// them and decodes what the C++ side encodes, and tools/lcm_spy.sh starts
// lcm-spy with them (or says clearly that the jar is missing). The jar tests
// need javac and jar at configure time and are skipped with a message
// otherwise.

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tests/lcmtypes/test_messages.h"
#include "tests/support/test_support.h"

namespace ag {
namespace {

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// Runs a shell command with its output into a file; returns the exit status
/// and the output.
int RunShell(const std::string& command, const std::string& output_file, std::string* output) {
  const int status = std::system((command + " > \"" + output_file + "\" 2>&1").c_str());
  *output = ReadFile(output_file);
  return status;
}

TEST(LcmSpyScript, SaysClearlyWhenTheJarIsNotBuilt) {
  test::TempDir dir;
  std::string output;
  const int status =
      RunShell("AG_BUILD_DIR=\"" + dir.path() + "\" AG_LCMTYPES_JAR= \"" + AG_LCM_SPY_SCRIPT + "\"",
               dir / "out.txt", &output);
  EXPECT_NE(status, 0);
  EXPECT_NE(output.find(dir.path() + "/lcmtypes/ag_lcmtypes.jar is not built"), std::string::npos)
      << output;
  EXPECT_NE(output.find("--target ag_lcmtypes_jar"), std::string::npos) << output;
}

#ifdef AG_LCMTYPES_JAR

constexpr const char* kMessageNames[] = {"quantized_array_t", "air_keyframe_t", "camera_info_t",
                                         "relative_pose_t",   "image_t",        "odometry_t",
                                         "point_cloud_t"};

template <class Msg>
std::string WriteEncoded(const Msg& msg, const std::string& path) {
  const std::vector<uint8_t> buf = test::Encode(msg);
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(buf.data()), static_cast<std::streamsize>(buf.size()));
  return path;
}

TEST(LcmJava, JarHoldsEveryMessageClass) {
  const std::string jar = ReadFile(AG_LCMTYPES_JAR);
  ASSERT_FALSE(jar.empty()) << AG_LCMTYPES_JAR << " is missing or empty";
  EXPECT_EQ(jar.substr(0, 4), std::string("PK\x03\x04", 4)) << "not a zip/jar file";
  // Zip stores entry names uncompressed, so the names are in the bytes.
  for (const char* name : kMessageNames) {
    EXPECT_NE(jar.find(std::string("aglcm/") + name + ".class"), std::string::npos) << name;
  }
}

TEST(LcmJava, LcmSpyTypeDatabaseDecodesWhatCppEncodes) {
  test::TempDir dir;
  const std::vector<std::string> files = {
      WriteEncoded(test::MakeAirKeyframe(20), dir / "keyframe.lcm"),
      WriteEncoded(test::MakeRelativePose(), dir / "pose.lcm"),
      WriteEncoded(test::MakeCameraInfo(), dir / "camera_info.lcm"),
      WriteEncoded(test::MakeImage(), dir / "image.lcm"),
      WriteEncoded(test::MakeOdometry(), dir / "odometry.lcm"),
      WriteEncoded(test::MakePointCloud(), dir / "cloud.lcm"),
      WriteEncoded(test::MakeQuantized(aglcm::quantized_array_t::FLOAT16, 2, 3, 16, false, 1),
                   dir / "quantized.lcm")};
  std::ostringstream command;
  command << "\"" << AG_JAVA << "\" -Djava.awt.headless=true -cp \"" << AG_LCM_JAR << ":"
          << AG_LCMTYPES_JAR << "\" \"" << AG_SPY_CHECK_JAVA << "\"";
  for (const std::string& f : files) command << " \"" << f << "\"";
  std::string output;
  const int status = RunShell(command.str(), dir / "out.txt", &output);
  ASSERT_EQ(status, 0) << command.str() << "\n" << output;

  std::map<std::string, std::string> fields;  // "<file index> <field>" -> value
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);) {
    const size_t eq = line.find('=');
    if (eq != std::string::npos) fields[line.substr(0, eq)] = line.substr(eq + 1);
  }
  EXPECT_EQ(fields["0 class"], "aglcm.air_keyframe_t") << output;
  EXPECT_EQ(fields["0 agent"], "uav_1");
  EXPECT_EQ(fields["0 seq"], "4242");
  EXPECT_EQ(fields["0 part"], "2");
  EXPECT_EQ(fields["0 num_parts"], "3");
  EXPECT_EQ(fields["0 t_ns"], "1700000000123456789");
  EXPECT_EQ(fields["0 position"], "[1.5, -2.25, 10.125]");
  EXPECT_EQ(fields["0 orientation"], "[0.5, -0.5, 0.5, -0.5]");
  EXPECT_EQ(fields["0 num_keypoints"], "20");
  EXPECT_EQ(fields["0 kp_x.length"], "20");
  EXPECT_EQ(fields["0 global_descriptor.dim"], "512");
  EXPECT_EQ(fields["0 descriptors.encoding"], "3");
  EXPECT_EQ(fields["0 descriptors.bits"], "4");
  EXPECT_EQ(fields["0 descriptors.num_bytes"], "640");
  EXPECT_EQ(fields["1 class"], "aglcm.relative_pose_t");
  EXPECT_EQ(fields["1 status_reason"], "tracking: 143 inliers");
  EXPECT_EQ(fields["1 x"], "12.5");
  EXPECT_EQ(fields["1 yaw"], "-2.1");
  EXPECT_EQ(fields["2 class"], "aglcm.camera_info_t");
  EXPECT_EQ(fields["2 model"], "equidistant");
  EXPECT_EQ(fields["2 has_T_body_camera"], "true");
  EXPECT_EQ(fields["3 class"], "aglcm.image_t");
  EXPECT_EQ(fields["3 encoding"], "bgr8");
  EXPECT_EQ(fields["4 class"], "aglcm.odometry_t");
  EXPECT_EQ(fields["4 world_frame_id"], "wg");
  EXPECT_EQ(fields["5 class"], "aglcm.point_cloud_t");
  EXPECT_EQ(fields["5 num_points"], "100");
  EXPECT_EQ(fields["6 class"], "aglcm.quantized_array_t");
  EXPECT_EQ(fields["6 num_bytes"], "12");
}

TEST(LcmSpyScript, StartsLcmSpyWithEveryOneOfOurTypes) {
  // Headless, lcm-spy gets as far as loading its type database ("Found N LCM
  // types") and then stops where it would open its window. memq:// keeps LCM
  // in-process: nothing touches the network. CLASSPATH is cleared because
  // lcm-spy scans it too; `timeout` bounds the run should a window open.
  test::TempDir dir;
  std::string output;
  RunShell(std::string("CLASSPATH= JAVA_TOOL_OPTIONS=-Djava.awt.headless=true JAVA=\"") + AG_JAVA +
               "\" AG_LCMTYPES_JAR=\"" + AG_LCMTYPES_JAR + "\" timeout 120 \"" + AG_LCM_SPY_SCRIPT +
               "\" --lcm-url=memq://",
           dir / "out.txt", &output);
  const std::string expected = "Found " + std::to_string(std::size(kMessageNames)) + " LCM types";
  EXPECT_NE(output.find(expected), std::string::npos) << output;
}

#else

TEST(LcmJava, JarHoldsEveryMessageClass) {
  GTEST_SKIP() << "javac, jar or /usr/share/java/lcm.jar were not found when CMake configured, "
                  "so ag_lcmtypes.jar (for lcm-spy) was not built; install default-jdk-headless "
                  "and liblcm-java and reconfigure";
}

#endif

}  // namespace
}  // namespace ag
