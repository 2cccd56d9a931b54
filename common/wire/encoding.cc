#include "common/wire/encoding.h"

namespace ag {

const char* ToString(ArrayEncoding encoding) {
  switch (encoding) {
    case ArrayEncoding::kFloat32:
      return "float32";
    case ArrayEncoding::kFloat16:
      return "float16";
    case ArrayEncoding::kInt8:
      return "int8";
    case ArrayEncoding::kBits4:
      return "bits4";
  }
  return "?";
}

std::optional<ArrayEncoding> ParseArrayEncoding(const std::string& name) {
  for (ArrayEncoding e : {ArrayEncoding::kFloat32, ArrayEncoding::kFloat16, ArrayEncoding::kInt8,
                          ArrayEncoding::kBits4}) {
    if (name == ToString(e)) return e;
  }
  return std::nullopt;
}

}  // namespace ag
