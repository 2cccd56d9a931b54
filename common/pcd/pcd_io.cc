#include "common/pcd/pcd_io.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <stdexcept>

#include "common/core/error.h"

namespace ag {
namespace {

const char* TypeName(uint8_t datatype) {
  switch (datatype) {
    case pcl::PCLPointField::INT8:
      return "int8";
    case pcl::PCLPointField::UINT8:
      return "uint8";
    case pcl::PCLPointField::INT16:
      return "int16";
    case pcl::PCLPointField::UINT16:
      return "uint16";
    case pcl::PCLPointField::INT32:
      return "int32";
    case pcl::PCLPointField::UINT32:
      return "uint32";
    case pcl::PCLPointField::FLOAT32:
      return "float32";
    case pcl::PCLPointField::FLOAT64:
      return "float64";
    default:
      return "an unknown type";
  }
}

// The field called `name`, or nullptr. Checks it is one float32.
const pcl::PCLPointField* FindFloatField(const pcl::PCLPointCloud2& blob, const std::string& name,
                                         const std::string& path, bool required) {
  for (const pcl::PCLPointField& f : blob.fields) {
    if (f.name != name) continue;
    if (f.datatype != pcl::PCLPointField::FLOAT32 || f.count != 1) {
      throw InputError(InputErrorKind::kBadValue, path, 0,
                       "field '" + name + "' is " + std::to_string(f.count) + " x " +
                           TypeName(f.datatype) + "; the dataset format needs one float32");
    }
    if (f.offset + sizeof(float) > blob.point_step) {
      throw InputError(InputErrorKind::kMalformedRow, path, 0,
                       "field '" + name + "' lies outside the point record");
    }
    return &f;
  }
  if (required) {
    std::string names;
    for (const pcl::PCLPointField& f : blob.fields) names += (names.empty() ? "" : " ") + f.name;
    throw InputError(InputErrorKind::kMissingField, path, 0,
                     "no '" + name + "' field (fields: " + names + "); x y z are required");
  }
  return nullptr;
}

// What CheckFile learnt about a PCD file.
struct PcdLayout {
  int64_t data_line = 0;  ///< line of "DATA ascii" (0 for binary files)
};

// PCL 1.13 crashes on some files that are not PCD at all (no FIELDS line)
// and reads unparsable or short ascii rows as zeros, so the file is checked
// here first: known header keywords only, the required ones present, FIELDS /
// SIZE / TYPE / COUNT of equal non-zero length, and for ascii data every row
// with exactly sum(COUNT) numbers.
PcdLayout CheckFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open the scan file");
  static constexpr const char* kKeywords[] = {"VERSION", "FIELDS", "SIZE",      "TYPE",   "COUNT",
                                              "WIDTH",   "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
  std::map<std::string, std::vector<std::string>> header;  // keyword -> values
  std::string line;
  int64_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream tokens(line);
    std::string keyword;
    if (!(tokens >> keyword) || keyword[0] == '#') continue;
    if (std::find(std::begin(kKeywords), std::end(kKeywords), keyword) == std::end(kKeywords)) {
      throw InputError(InputErrorKind::kMalformedRow, path, line_no,
                       "not a PCD header line (expected VERSION, FIELDS, SIZE, TYPE, COUNT, "
                       "WIDTH, HEIGHT, VIEWPOINT, POINTS or DATA before the data)");
    }
    std::vector<std::string>& values = header[keyword];
    for (std::string value; tokens >> value;) values.push_back(value);
    if (keyword == "DATA") break;
  }
  for (const char* required : {"FIELDS", "SIZE", "TYPE", "WIDTH", "POINTS", "DATA"}) {
    if (!header.count(required)) {
      throw InputError(InputErrorKind::kMalformedRow, path, 0,
                       std::string("not a PCD file: the header has no ") + required + " line");
    }
  }
  const size_t num_fields = header["FIELDS"].size();
  const bool has_count = header.count("COUNT") > 0;
  if (num_fields == 0 || header["SIZE"].size() != num_fields ||
      header["TYPE"].size() != num_fields || (has_count && header["COUNT"].size() != num_fields)) {
    throw InputError(InputErrorKind::kMalformedRow, path, 0,
                     "FIELDS, SIZE, TYPE and COUNT must list the same non-zero number of values");
  }
  PcdLayout layout;
  if (header["DATA"].empty() || header["DATA"][0] != "ascii") return layout;
  layout.data_line = line_no;

  size_t values_per_point = 0;
  for (size_t k = 0; k < num_fields; ++k) {
    values_per_point += has_count ? std::strtoul(header["COUNT"][k].c_str(), nullptr, 10) : 1;
  }
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream tokens(line);
    size_t n = 0;
    for (std::string value; tokens >> value; ++n) {
      char* end = nullptr;
      std::strtod(value.c_str(), &end);
      if (end == value.c_str() || *end != '\0') {
        throw InputError(InputErrorKind::kMalformedRow, path, line_no,
                         "'" + value + "' is not a number");
      }
    }
    if (n != 0 && n != values_per_point) {
      throw InputError(
          InputErrorKind::kMalformedRow, path, line_no,
          "expected " + std::to_string(values_per_point) + " values, got " + std::to_string(n));
    }
  }
  return layout;
}

float ReadFloat(const uint8_t* record, const pcl::PCLPointField& field) {
  float value;
  std::memcpy(&value, record + field.offset, sizeof(value));
  return value;
}

}  // namespace

PointCloud ReadScan(const std::string& pcd_path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(pcd_path, ec)) {
    throw InputError(InputErrorKind::kMissingFile, pcd_path, 0, "scan file does not exist");
  }
  const PcdLayout layout = CheckFile(pcd_path);
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int pcd_version = 0;
  pcl::PCDReader reader;
  if (reader.read(pcd_path, blob, origin, orientation, pcd_version) < 0) {
    throw InputError(InputErrorKind::kMalformedRow, pcd_path, 0,
                     "not a readable PCD file (PCL could not parse it)");
  }
  const pcl::PCLPointField* fx = FindFloatField(blob, "x", pcd_path, true);
  const pcl::PCLPointField* fy = FindFloatField(blob, "y", pcd_path, true);
  const pcl::PCLPointField* fz = FindFloatField(blob, "z", pcd_path, true);
  const pcl::PCLPointField* fi = FindFloatField(blob, "intensity", pcd_path, false);

  const size_t n = static_cast<size_t>(blob.width) * blob.height;
  if (blob.data.size() < n * blob.point_step) {
    throw InputError(InputErrorKind::kMalformedRow, pcd_path, 0,
                     "holds " + std::to_string(blob.data.size()) + " bytes of data for " +
                         std::to_string(n) + " points of " + std::to_string(blob.point_step) +
                         " bytes");
  }
  PointCloud cloud;
  cloud.points.resize(n);
  if (fi) cloud.intensity.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* record = blob.data.data() + i * blob.point_step;
    Eigen::Vector3f& p = cloud.points[i];
    p = Eigen::Vector3f(ReadFloat(record, *fx), ReadFloat(record, *fy), ReadFloat(record, *fz));
    const float intensity = fi ? ReadFloat(record, *fi) : 0.0f;
    if (!p.allFinite() || !std::isfinite(intensity)) {
      // One point per row after the DATA line (CheckFile made sure of it).
      const int64_t line =
          layout.data_line > 0 ? layout.data_line + 1 + static_cast<int64_t>(i) : 0;
      throw InputError(InputErrorKind::kNonFinite, pcd_path, line,
                       "point " + std::to_string(i) +
                           " is not finite (the dataset format has no "
                           "NaN placeholders; drop invalid returns before writing)");
    }
    if (fi) cloud.intensity[i] = intensity;
  }
  return cloud;
}

void WriteScan(const std::string& path, const PointCloud& cloud, bool binary) {
  const bool has_intensity = !cloud.intensity.empty();
  if (has_intensity && cloud.intensity.size() != cloud.points.size()) {
    throw std::invalid_argument("WriteScan: " + std::to_string(cloud.intensity.size()) +
                                " intensities for " + std::to_string(cloud.points.size()) +
                                " points");
  }
  pcl::PCLPointCloud2 blob;
  const char* names[4] = {"x", "y", "z", "intensity"};
  const int num_fields = has_intensity ? 4 : 3;
  for (int k = 0; k < num_fields; ++k) {
    pcl::PCLPointField field;
    field.name = names[k];
    field.offset = static_cast<uint32_t>(k * sizeof(float));
    field.datatype = pcl::PCLPointField::FLOAT32;
    field.count = 1;
    blob.fields.push_back(field);
  }
  blob.point_step = static_cast<uint32_t>(num_fields * sizeof(float));
  blob.width = static_cast<uint32_t>(cloud.points.size());
  blob.height = 1;
  blob.row_step = blob.point_step * blob.width;
  blob.is_dense = true;
  blob.data.resize(static_cast<size_t>(blob.row_step));
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    float record[4];
    const Eigen::Vector3f& p = cloud.points[i];
    record[0] = p.x();
    record[1] = p.y();
    record[2] = p.z();
    record[3] = has_intensity ? cloud.intensity[i] : 0.0f;
    if (!p.allFinite() || !std::isfinite(record[3])) {
      throw std::invalid_argument("WriteScan: point " + std::to_string(i) + " is not finite");
    }
    std::memcpy(blob.data.data() + i * blob.point_step, record, blob.point_step);
  }
  pcl::PCDWriter writer;
  // 9 significant digits make ascii float32 values read back exactly.
  const int result = binary ? writer.writeBinary(path, blob)
                            : writer.writeASCII(path, blob, Eigen::Vector4f::Zero(),
                                                Eigen::Quaternionf::Identity(), 9);
  if (result < 0) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot write the scan");
}

}  // namespace ag
