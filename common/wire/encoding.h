#pragma once

#include <optional>
#include <string>

namespace ag {

/// How a float array (descriptors) travels in a packet, richest first.
/// float32 is the paper's 4 bytes per dimension.
enum class ArrayEncoding {
  kFloat32,  ///< IEEE binary32, 4 bytes per value
  kFloat16,  ///< IEEE binary16, 2 bytes per value
  kInt8,     ///< int8 with one scale per vector, 1 byte per value
  kBits4,    ///< 4-bit codes with per-vector offset and scale, 0.5 byte per value
};

const char* ToString(ArrayEncoding encoding);

/// Parses "float32", "float16", "int8", "bits4"; nullopt otherwise.
std::optional<ArrayEncoding> ParseArrayEncoding(const std::string& name);

}  // namespace ag
