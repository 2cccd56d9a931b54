#pragma once

// Strict YAML reading and exact YAML writing shared by the dataset files
// (dataset.yaml, calibration.yaml, groundtruth.yaml). Internal to
// ag::dataset: every error is an ag::InputError naming the file, the line
// (from yaml-cpp marks, 1-based) and the dotted key.

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "common/geometry/pose.h"

namespace ag::internal {

/// Largest deviation of a stored rotation block from orthonormality that the
/// readers accept (max |R^T R - I| and |det R - 1|); the same tolerance as
/// ReadTum's quaternion norm. Matrices within it are replaced by the nearest
/// rotation unless already orthonormal to 1e-12, so exact files stay exact.
constexpr double kRotationTolerance = 1e-3;

/// A YAML file being read: its path (for messages) and root node.
struct YamlDoc {
  std::string path;
  YAML::Node root;
};

/// Loads a YAML file (InputError kMissingFile / kMalformedRow with the line
/// of a syntax error).
YamlDoc LoadYaml(const std::string& path);

/// 1-based line of `node`, 0 when yaml-cpp has no mark for it.
int64_t LineOf(const YAML::Node& node);

/// Checks that `node` (named `name`, "" for the root) is a map whose keys
/// are all in `known` and appear once. Throws kBadValue (not a map; an
/// empty file is reported as kMissingField), kUnknownKey naming the key, or
/// kMalformedRow for a duplicate key.
void CheckMap(const YamlDoc& doc, const YAML::Node& node, const std::string& name,
              std::initializer_list<const char*> known);

/// node[key] of a map checked by CheckMap; throws kMissingField naming the
/// dotted key and the line of the parent when absent.
YAML::Node Require(const YamlDoc& doc, const YAML::Node& map, const std::string& map_name,
                   const char* key);

/// Joins a parent name and a key with '.'.
std::string Dotted(const std::string& parent, const std::string& key);

/// Scalars. Numbers are parsed strictly (the whole text must be a number):
/// kMalformedRow when unparsable, kNonFinite for nan / inf (.nan, .inf too),
/// kBadValue when the node is not a scalar.
double ReadDouble(const YamlDoc& doc, const YAML::Node& node, const std::string& name);
int64_t ReadInt(const YamlDoc& doc, const YAML::Node& node, const std::string& name);
/// A scalar as text; a null node (key with no value) reads as "".
std::string ReadString(const YamlDoc& doc, const YAML::Node& node, const std::string& name);
/// A list of numbers; `expected_size` < 0 accepts any length.
std::vector<double> ReadDoubleList(const YamlDoc& doc, const YAML::Node& node,
                                   const std::string& name, int expected_size = -1);
/// A 4x4 transform as 4 lists of 4 numbers, row-major. kMalformedRow for a
/// wrong shape; kNotRotation when the last row is not 0 0 0 1 or the
/// rotation block is not orthonormal (see kRotationTolerance).
Pose ReadTransform(const YamlDoc& doc, const YAML::Node& node, const std::string& name);

/// The shortest decimal text that parses back to exactly `value` (at most
/// 17 significant digits, "%.17g" when nothing shorter is exact); exponent
/// notation only below 1e-4 or from 1e15 on.
std::string FormatDouble(double value);
/// "[a, b, ...]" with FormatDouble.
std::string FormatList(const std::vector<double>& values);
/// "[[r0], [r1], [r2], [r3]]" row-major; rows after the first on their own
/// line, aligned under the first '[' when it sits at column `column`.
std::string FormatTransform(const Pose& T, int column);
/// A double-quoted YAML string with escapes, for free text.
std::string QuoteString(const std::string& text);

/// Writes `text` to `path`; InputError(kMissingFile) when it cannot.
void WriteTextFile(const std::string& path, const std::string& text);

}  // namespace ag::internal
