#pragma once

// LiDAR scans of a dataset (scans/*.pcd, ../shared/spec/dataset.md): PCL PCD
// v0.7, ascii or binary, float32 fields x y z and optionally intensity, in
// the LiDAR frame. Ground side only (ag::pcd links PCL; its headers stay in
// pcd_io.cc).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace ag {

/// A scan's points (LiDAR frame, m) and, when the file has it, intensity.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;  ///< one per point, or empty if absent
};

/// Reads a PCD file (ascii, binary or binary_compressed; organised clouds are
/// read row by row; fields other than x y z intensity are ignored). Throws
/// ag::InputError naming the file: kMissingFile, kMalformedRow (PCL cannot
/// parse it), kMissingField (no x, y or z), kBadValue (x y z or intensity not
/// a single float32), kNonFinite (a NaN/inf coordinate or intensity; the line
/// is given for ascii files).
PointCloud ReadScan(const std::string& pcd_path);

/// Writes a PCD v0.7 file, binary or ascii (9 significant digits, so float32
/// values read back exactly), with an intensity field when
/// cloud.intensity is non-empty. Throws std::invalid_argument when
/// intensity has the wrong size or a value is not finite (such a scan would
/// not read back), InputError(kMissingFile) when the file cannot be written.
void WriteScan(const std::string& path, const PointCloud& cloud, bool binary = true);

}  // namespace ag
