#include "common/geometry/tum_io.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "common/core/error.h"

namespace ag {

bool ParseDecimalSecondsNs(const std::string& text, int64_t* t_ns) {
  if (text.empty()) return false;
  size_t i = 0;
  const bool negative = text[0] == '-';
  if (negative) i = 1;
  int64_t seconds = 0;
  int64_t fraction = 0;
  int int_digits = 0;
  int frac_digits = 0;
  for (; i < text.size() && text[i] != '.'; ++i) {
    if (text[i] < '0' || text[i] > '9' || int_digits >= 11) return false;
    seconds = seconds * 10 + (text[i] - '0');
    ++int_digits;
  }
  if (i < text.size()) {  // at '.'
    for (++i; i < text.size(); ++i) {
      if (text[i] < '0' || text[i] > '9' || frac_digits >= 9) return false;
      fraction = fraction * 10 + (text[i] - '0');
      ++frac_digits;
    }
  }
  if (int_digits == 0 && frac_digits == 0) return false;
  for (int k = frac_digits; k < 9; ++k) fraction *= 10;
  const int64_t value = seconds * 1000000000LL + fraction;
  *t_ns = negative ? -value : value;
  return true;
}

std::string FormatDecimalSecondsNs(int64_t t_ns) {
  const bool negative = t_ns < 0;
  const uint64_t abs_ns = negative ? static_cast<uint64_t>(-(t_ns + 1)) + 1 : t_ns;
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(abs_ns / 1000000000ULL),
                static_cast<unsigned long long>(abs_ns % 1000000000ULL));
  return buf;
}

std::vector<StampedPose> ReadTum(const std::string& path, double quaternion_tolerance) {
  std::ifstream in(path);
  if (!in) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open TUM trajectory");
  std::vector<StampedPose> poses;
  std::string line;
  int64_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    std::vector<std::string> tokens;
    for (std::string tok; fields >> tok;) tokens.push_back(tok);
    if (tokens.size() != 8) {
      throw InputError(InputErrorKind::kMalformedRow, path, line_no,
                       "expected 8 fields 'timestamp tx ty tz qx qy qz qw', got " +
                           std::to_string(tokens.size()));
    }
    StampedPose pose;
    if (!ParseDecimalSecondsNs(tokens[0], &pose.t_ns)) {
      // Tolerate exponent notation from other tools, through a double.
      char* end = nullptr;
      const double t = std::strtod(tokens[0].c_str(), &end);
      if (end == tokens[0].c_str() || *end != '\0') {
        throw InputError(InputErrorKind::kMalformedRow, path, line_no,
                         "timestamp '" + tokens[0] + "' is not a number");
      }
      if (!std::isfinite(t)) {
        throw InputError(InputErrorKind::kNonFinite, path, line_no,
                         "timestamp '" + tokens[0] + "' is not finite");
      }
      pose.t_ns = static_cast<int64_t>(std::llround(t * 1e9));
    }
    double v[7];
    static const char* kNames[7] = {"tx", "ty", "tz", "qx", "qy", "qz", "qw"};
    for (int k = 0; k < 7; ++k) {
      const std::string& tok = tokens[k + 1];
      char* end = nullptr;
      v[k] = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0') {
        throw InputError(InputErrorKind::kMalformedRow, path, line_no,
                         std::string(kNames[k]) + " '" + tok + "' is not a number");
      }
      if (!std::isfinite(v[k])) {
        throw InputError(InputErrorKind::kNonFinite, path, line_no,
                         std::string(kNames[k]) + " is " + tok);
      }
    }
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (std::abs(q.norm() - 1.0) > quaternion_tolerance) {
      throw InputError(InputErrorKind::kNotRotation, path, line_no,
                       "quaternion norm " + std::to_string(q.norm()) + " is not 1");
    }
    q.normalize();
    pose.T.linear() = q.toRotationMatrix();
    pose.T.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    if (!poses.empty() && pose.t_ns <= poses.back().t_ns) {
      throw InputError(InputErrorKind::kUnsorted, path, line_no,
                       "timestamp " + tokens[0] + " is not after the previous one (" +
                           FormatDecimalSecondsNs(poses.back().t_ns) + ")");
    }
    poses.push_back(pose);
  }
  return poses;
}

void WriteTum(const std::string& path, const std::vector<StampedPose>& poses,
              const std::string& header_comment) {
  std::ofstream out(path);
  if (!out) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot write TUM trajectory");
  out << "# " << (header_comment.empty() ? "timestamp tx ty tz qx qy qz qw" : header_comment)
      << "\n";
  char buf[256];
  for (const StampedPose& p : poses) {
    const Eigen::Quaterniond q(p.T.linear());
    const Eigen::Vector3d t = p.T.translation();
    std::snprintf(buf, sizeof(buf), " %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", t.x(), t.y(),
                  t.z(), q.x(), q.y(), q.z(), q.w());
    out << FormatDecimalSecondsNs(p.t_ns) << buf;
  }
  if (!out) throw InputError(InputErrorKind::kMissingFile, path, 0, "write failed");
}

}  // namespace ag
