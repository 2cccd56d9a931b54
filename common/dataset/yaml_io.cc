#include "common/dataset/yaml_io.h"

#include <Eigen/SVD>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "common/config/options.h"
#include "common/core/error.h"

namespace ag::internal {
namespace {

std::string Quoted(const std::string& name) { return "'" + name + "'"; }

std::string Trim(const std::string& text) {
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return "";
  const size_t last = text.find_last_not_of(" \t\r\n");
  return text.substr(first, last - first + 1);
}

// The scalar text of a number-valued node, or an error naming the key.
std::string NumberText(const YamlDoc& doc, const YAML::Node& node, const std::string& name) {
  if (node.IsNull()) {
    throw InputError(InputErrorKind::kMissingField, doc.path, LineOf(node),
                     Quoted(name) + " has no value");
  }
  if (!node.IsScalar()) {
    throw InputError(InputErrorKind::kBadValue, doc.path, LineOf(node),
                     Quoted(name) + " must be a number, not a list or map");
  }
  return Trim(node.Scalar());
}

}  // namespace

YamlDoc LoadYaml(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(InputErrorKind::kMissingFile, path, 0, "file does not exist");
  }
  return YamlDoc{path, LoadYamlFile(path)};
}

int64_t LineOf(const YAML::Node& node) {
  if (!node.IsDefined()) return 0;
  const YAML::Mark mark = node.Mark();
  return mark.is_null() ? 0 : mark.line + 1;
}

std::string Dotted(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

void CheckMap(const YamlDoc& doc, const YAML::Node& node, const std::string& name,
              std::initializer_list<const char*> known) {
  std::string known_list;
  for (const char* k : known) known_list += (known_list.empty() ? "" : ", ") + std::string(k);
  if (!node.IsDefined() || node.IsNull()) {
    throw InputError(InputErrorKind::kMissingField, doc.path, LineOf(node),
                     (name.empty() ? std::string("the file") : Quoted(name)) +
                         " is empty; expected a map with " + known_list);
  }
  if (!node.IsMap()) {
    throw InputError(InputErrorKind::kBadValue, doc.path, LineOf(node),
                     (name.empty() ? std::string("the file") : Quoted(name)) +
                         " must be a map with " + known_list);
  }
  std::vector<std::string> seen;
  for (const auto& kv : node) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : "<non-scalar key>";
    bool is_known = false;
    for (const char* k : known) is_known = is_known || key == k;
    if (!is_known) {
      throw InputError(InputErrorKind::kUnknownKey, doc.path, LineOf(kv.first),
                       "unknown key " + Quoted(Dotted(name, key)) + " (known: " + known_list + ")");
    }
    for (const std::string& s : seen) {
      if (s == key) {
        throw InputError(InputErrorKind::kMalformedRow, doc.path, LineOf(kv.first),
                         "duplicate key " + Quoted(Dotted(name, key)));
      }
    }
    seen.push_back(key);
  }
}

YAML::Node Require(const YamlDoc& doc, const YAML::Node& map, const std::string& map_name,
                   const char* key) {
  const YAML::Node child = map[key];
  if (!child.IsDefined()) {
    throw InputError(InputErrorKind::kMissingField, doc.path, map_name.empty() ? 0 : LineOf(map),
                     "required key " + Quoted(Dotted(map_name, key)) + " is missing");
  }
  return child;
}

double ReadDouble(const YamlDoc& doc, const YAML::Node& node, const std::string& name) {
  const std::string text = NumberText(doc, node, name);
  std::string lower;
  for (char c : text) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  // YAML 1.2 spells non-finite floats .nan / .inf; strtod knows nan / inf.
  if (lower == ".nan" || lower == ".inf" || lower == "+.inf" || lower == "-.inf") {
    throw InputError(InputErrorKind::kNonFinite, doc.path, LineOf(node),
                     Quoted(name) + " is " + text);
  }
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size()) {
    throw InputError(InputErrorKind::kMalformedRow, doc.path, LineOf(node),
                     Quoted(name) + ": '" + text + "' is not a number");
  }
  if (!std::isfinite(value)) {
    throw InputError(InputErrorKind::kNonFinite, doc.path, LineOf(node),
                     Quoted(name) + " is " + text);
  }
  return value;
}

int64_t ReadInt(const YamlDoc& doc, const YAML::Node& node, const std::string& name) {
  const std::string text = NumberText(doc, node, name);
  char* end = nullptr;
  errno = 0;
  const long long value = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE) {
    throw InputError(InputErrorKind::kMalformedRow, doc.path, LineOf(node),
                     Quoted(name) + ": '" + text + "' is not an integer");
  }
  return value;
}

std::string ReadString(const YamlDoc& doc, const YAML::Node& node, const std::string& name) {
  if (node.IsNull()) return "";
  if (!node.IsScalar()) {
    throw InputError(InputErrorKind::kBadValue, doc.path, LineOf(node),
                     Quoted(name) + " must be text, not a list or map");
  }
  return node.Scalar();
}

std::vector<double> ReadDoubleList(const YamlDoc& doc, const YAML::Node& node,
                                   const std::string& name, int expected_size) {
  if (!node.IsSequence()) {
    throw InputError(InputErrorKind::kBadValue, doc.path, LineOf(node),
                     Quoted(name) + " must be a list of numbers");
  }
  if (expected_size >= 0 && static_cast<int>(node.size()) != expected_size) {
    throw InputError(InputErrorKind::kMalformedRow, doc.path, LineOf(node),
                     Quoted(name) + " needs " + std::to_string(expected_size) + " numbers, got " +
                         std::to_string(node.size()));
  }
  std::vector<double> values;
  values.reserve(node.size());
  for (size_t i = 0; i < node.size(); ++i) {
    values.push_back(ReadDouble(doc, node[i], name + "[" + std::to_string(i) + "]"));
  }
  return values;
}

Pose ReadTransform(const YamlDoc& doc, const YAML::Node& node, const std::string& name) {
  const std::string shape = " must be a 4x4 matrix written as a list of 4 lists of 4 numbers";
  if (!node.IsSequence() || node.size() != 4) {
    throw InputError(
        InputErrorKind::kMalformedRow, doc.path, LineOf(node),
        Quoted(name) + shape +
            (node.IsSequence() ? ", got " + std::to_string(node.size()) + " rows" : std::string()));
  }
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r) {
    const YAML::Node row = node[r];
    if (!row.IsSequence() || row.size() != 4) {
      throw InputError(InputErrorKind::kMalformedRow, doc.path, LineOf(row),
                       Quoted(name) + shape + "; row " + std::to_string(r) + " is not 4 numbers");
    }
    for (int c = 0; c < 4; ++c) {
      M(r, c) =
          ReadDouble(doc, row[c], name + "[" + std::to_string(r) + "][" + std::to_string(c) + "]");
    }
  }
  if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    throw InputError(InputErrorKind::kNotRotation, doc.path, LineOf(node[3]),
                     Quoted(name) + ": last row must be 0 0 0 1");
  }
  Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if (!IsRotation(R, kRotationTolerance)) {
    const double ortho = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    char detail[128];
    std::snprintf(detail, sizeof(detail), " (max |R^T R - I| = %.3g, det = %.6g)", ortho,
                  R.determinant());
    throw InputError(InputErrorKind::kNotRotation, doc.path, LineOf(node),
                     Quoted(name) + ": the rotation block is not orthonormal" + detail);
  }
  if (!IsRotation(R, 1e-12)) {
    // Nearest rotation in the Frobenius norm (rounded input files).
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
    R = svd.matrixU() * D * svd.matrixV().transpose();
  }
  Pose T = Pose::Identity();
  T.linear() = R;
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

std::string FormatDouble(double value) {
  char buf[40];
  // Exponent notation only where it reads better than digits ("1e-05", not
  // "5e+02" for 500).
  const bool exponent_ok = std::abs(value) < 1e-4 || std::abs(value) >= 1e15;
  for (int precision = 1; precision < 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, value);
    if (std::strtod(buf, nullptr) == value && (exponent_ok || !std::strchr(buf, 'e'))) return buf;
  }
  std::snprintf(buf, sizeof(buf), "%.17g", value);
  return buf;
}

std::string FormatList(const std::vector<double>& values) {
  std::string out = "[";
  for (size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + FormatDouble(values[i]);
  return out + "]";
}

std::string FormatTransform(const Pose& T, int column) {
  const Eigen::Matrix4d& M = T.matrix();
  std::string out = "[";
  for (int r = 0; r < 4; ++r) {
    if (r > 0) out += ",\n" + std::string(column + 1, ' ');
    out += FormatList({M(r, 0), M(r, 1), M(r, 2), M(r, 3)});
  }
  return out + "]";
}

std::string QuoteString(const std::string& text) {
  std::string out = "\"";
  for (const char ch : text) {
    const unsigned char c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (c < 0x20 || c == 0x7f) {
          char esc[8];
          std::snprintf(esc, sizeof(esc), "\\x%02x", c);
          out += esc;
        } else {
          out += ch;
        }
    }
  }
  return out + "\"";
}

void WriteTextFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open for writing");
  out << text;
  out.close();
  if (!out) throw InputError(InputErrorKind::kMissingFile, path, 0, "write failed");
}

}  // namespace ag::internal
