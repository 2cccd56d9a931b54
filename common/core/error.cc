#include "common/core/error.h"

namespace ag {
namespace {

std::string FormatMessage(InputErrorKind kind, const std::string& file, int64_t line,
                          const std::string& problem) {
  std::string where = file;
  if (line > 0) where += ":" + std::to_string(line);
  return where + ": " + ToString(kind) + ": " + problem;
}

}  // namespace

const char* ToString(InputErrorKind kind) {
  switch (kind) {
    case InputErrorKind::kMissingFile:
      return "missing file";
    case InputErrorKind::kMalformedRow:
      return "malformed row";
    case InputErrorKind::kNonFinite:
      return "non-finite number";
    case InputErrorKind::kNotRotation:
      return "not a rotation";
    case InputErrorKind::kUnsorted:
      return "unsorted timestamp";
    case InputErrorKind::kMissingField:
      return "missing field";
    case InputErrorKind::kBadValue:
      return "bad value";
    case InputErrorKind::kUnknownKey:
      return "unknown key";
  }
  return "input error";
}

InputError::InputError(InputErrorKind kind, std::string file, int64_t line,
                       const std::string& problem)
    : std::runtime_error(FormatMessage(kind, file, line, problem)),
      kind_(kind),
      file_(std::move(file)),
      line_(line),
      problem_(problem) {}

}  // namespace ag
