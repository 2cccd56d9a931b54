#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/geometry/pose.h"

namespace ag {

/// Parses a decimal-seconds timestamp ("1700000000.123456789") exactly into
/// nanoseconds, without going through a double. Accepts up to 9 decimals
/// (more are rejected rather than rounded). Returns false on bad syntax.
bool ParseDecimalSecondsNs(const std::string& text, int64_t* t_ns);

/// Formats nanoseconds as decimal seconds with 9 decimals.
std::string FormatDecimalSecondsNs(int64_t t_ns);

/// Reads a TUM trajectory ("timestamp tx ty tz qx qy qz qw" per line, '#'
/// comments, blank lines allowed). Throws ag::InputError naming file, line
/// and problem on: missing file, wrong field count, unparsable or non-finite
/// number, quaternion norm off 1 by more than `quaternion_tolerance`, or a
/// timestamp not strictly greater than the previous one. Quaternions within
/// tolerance are normalised.
std::vector<StampedPose> ReadTum(const std::string& path, double quaternion_tolerance = 1e-3);

/// Writes a TUM trajectory with 9-decimal timestamps and full double
/// precision. Throws ag::InputError(kMissingFile) if the file cannot be
/// written.
void WriteTum(const std::string& path, const std::vector<StampedPose>& poses,
              const std::string& header_comment = "");

}  // namespace ag
