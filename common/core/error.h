#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace ag {

/// What is wrong with an input file. Tests and callers branch on the kind;
/// humans read the message, which always names file, line and problem.
enum class InputErrorKind {
  kMissingFile,   ///< file or directory does not exist / cannot be opened
  kMalformedRow,  ///< wrong number of fields, unparsable number, bad syntax
  kNonFinite,     ///< NaN or infinity where a number is required
  kNotRotation,   ///< rotation / quaternion not orthonormal / unit
  kUnsorted,      ///< timestamps not strictly increasing
  kMissingField,  ///< a required YAML key or CSV column is absent
  kBadValue,      ///< a value out of range or of the wrong type
  kUnknownKey,    ///< a YAML key that no option reads (typo guard)
};

/// Human-readable name of an error kind ("non-finite number", ...).
const char* ToString(InputErrorKind kind);

/// Thrown by every reader of on-disk or configuration input.
/// `line` is 1-based; 0 means "the whole file" (e.g. a missing file).
class InputError : public std::runtime_error {
 public:
  InputError(InputErrorKind kind, std::string file, int64_t line, const std::string& problem);

  InputErrorKind kind() const { return kind_; }
  const std::string& file() const { return file_; }
  int64_t line() const { return line_; }
  const std::string& problem() const { return problem_; }

 private:
  InputErrorKind kind_;
  std::string file_;
  int64_t line_;
  std::string problem_;
};

/// Thrown by an Options struct's Check() for an invalid value; the config
/// loader turns it into an InputError naming the file and the dotted field.
class OptionError : public std::invalid_argument {
 public:
  OptionError(const std::string& field, const std::string& problem)
      : std::invalid_argument(field + " " + problem), field_(field) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

/// Throws OptionError(field, problem) unless `condition` holds.
inline void CheckOption(bool condition, const std::string& field, const std::string& problem) {
  if (!condition) throw OptionError(field, problem);
}

}  // namespace ag
