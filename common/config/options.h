#pragma once

// Options structs <-> YAML, written once per struct.
//
// Every Options struct declares its fields with defaults and lists them once
// in a VisitFields template; the same list drives reading, unknown-key
// rejection, writing back and logging of the effective configuration:
//
//   struct MapOptions {
//     double voxel_size_m = 0.1;  ///< voxel edge length (m)
//     int max_voxels = 200000;    ///< memory cap (voxels)
//     template <class V> void VisitFields(V& v) {
//       v("voxel_size_m", voxel_size_m);
//       v("max_voxels", max_voxels);
//     }
//     void Check() const { CheckOption(voxel_size_m > 0, "voxel_size_m", "must be > 0"); }
//   };
//   auto opts = LoadOptionsFile<MapOptions>("config/ground.yaml", "map");
//
// Supported field types: bool, int, int64_t, uint32_t, float, double,
// std::string, std::vector of those, and nested structs with VisitFields.

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "common/core/error.h"

namespace ag {

namespace internal {

template <class T, class = void>
struct HasVisitFields : std::false_type {};
struct NullVisitor {
  template <class U>
  void operator()(const char*, U&) {}
};
template <class T>
struct HasVisitFields<
    T, std::void_t<decltype(std::declval<T&>().VisitFields(std::declval<NullVisitor&>()))>>
    : std::true_type {};

template <class T>
struct IsVector : std::false_type {};
template <class T, class A>
struct IsVector<std::vector<T, A>> : std::true_type {};

template <class T>
struct IsFloatVector : std::false_type {};
template <class T, class A>
struct IsFloatVector<std::vector<T, A>> : std::is_floating_point<T> {};

template <class T, class = void>
struct HasCheck : std::false_type {};
template <class T>
struct HasCheck<T, std::void_t<decltype(std::declval<const T&>().Check())>> : std::true_type {};

template <class T>
void CheckIfAvailable(const T& value) {
  if constexpr (HasCheck<T>::value) value.Check();
}

/// Reads scalars with a message naming the key on a type mismatch.
template <class T>
T ReadScalar(const YAML::Node& node, const std::string& source, const std::string& key) {
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    throw InputError(InputErrorKind::kBadValue, source, node.Mark().line + 1,
                     "'" + key + "' has the wrong type for this option");
  }
}

class ReadVisitor {
 public:
  ReadVisitor(const YAML::Node& node, std::string source, std::string prefix)
      : node_(node), source_(std::move(source)), prefix_(std::move(prefix)) {}

  template <class T>
  void operator()(const char* key, T& value) {
    seen_.emplace_back(key);
    const YAML::Node child = node_[key];
    if (!child.IsDefined() || child.IsNull()) return;  // keep the default
    Read(child, prefix_ + key, value);
  }

  /// Throws on keys present in YAML that no field read.
  void RejectUnknownKeys() const {
    if (!node_.IsMap()) return;
    for (const auto& kv : node_) {
      const std::string key = kv.first.as<std::string>();
      bool known = false;
      for (const std::string& s : seen_) known = known || s == key;
      if (!known) {
        std::string hint;
        for (const std::string& s : seen_) hint += (hint.empty() ? "" : ", ") + s;
        throw InputError(InputErrorKind::kUnknownKey, source_, kv.first.Mark().line + 1,
                         "'" + prefix_ + key + "' is not an option here (known: " + hint + ")");
      }
    }
  }

 private:
  template <class T>
  void Read(const YAML::Node& child, const std::string& name, T& value) {
    if constexpr (HasVisitFields<T>::value) {
      if (!child.IsMap()) {
        throw InputError(InputErrorKind::kBadValue, source_, child.Mark().line + 1,
                         "'" + name + "' must be a map");
      }
      ReadVisitor nested(child, source_, name + ".");
      value.VisitFields(nested);
      nested.RejectUnknownKeys();
    } else if constexpr (IsVector<T>::value) {
      if (!child.IsSequence()) {
        throw InputError(InputErrorKind::kBadValue, source_, child.Mark().line + 1,
                         "'" + name + "' must be a list");
      }
      value = ReadScalar<T>(child, source_, name);
    } else {
      if (!child.IsScalar()) {
        throw InputError(InputErrorKind::kBadValue, source_, child.Mark().line + 1,
                         "'" + name + "' must be a single value");
      }
      value = ReadScalar<T>(child, source_, name);
    }
  }

  const YAML::Node& node_;
  std::string source_;
  std::string prefix_;
  std::vector<std::string> seen_;
};

class WriteVisitor {
 public:
  explicit WriteVisitor(YAML::Node* node) : node_(node) {}
  template <class T>
  void operator()(const char* key, const T& value) {
    if constexpr (HasVisitFields<T>::value) {
      YAML::Node child(YAML::NodeType::Map);
      WriteVisitor nested(&child);
      const_cast<T&>(value).VisitFields(nested);
      (*node_)[key] = child;
    } else if constexpr (std::is_floating_point_v<T>) {
      (*node_)[key] = ShortestText(value);
    } else if constexpr (IsFloatVector<T>::value) {
      YAML::Node list(YAML::NodeType::Sequence);
      for (const auto& v : value) list.push_back(ShortestText(v));
      (*node_)[key] = list;
    } else {
      (*node_)[key] = value;
    }
  }

 private:
  /// The shortest decimal text that reads back as the same number, so the
  /// effective configuration shows 0.05, not 0.050000000000000003.
  static YAML::Node ShortestText(double value) {
    char buf[40];
    for (int digits = 6; digits <= 17; ++digits) {
      std::snprintf(buf, sizeof(buf), "%.*g", digits, value);
      if (std::strtod(buf, nullptr) == value) break;
    }
    return YAML::Node(std::string(buf));
  }

  YAML::Node* node_;
};

/// Applies Check() recursively (nested structs first) and names the field.
class CheckVisitor {
 public:
  explicit CheckVisitor(std::string prefix) : prefix_(std::move(prefix)) {}
  template <class T>
  void operator()(const char* key, const T& value) {
    if constexpr (HasVisitFields<T>::value) {
      CheckVisitor nested(prefix_ + key + ".");
      const_cast<T&>(value).VisitFields(nested);
      try {
        CheckIfAvailable(value);
      } catch (const OptionError& e) {
        throw OptionError(prefix_ + key + "." + e.field(),
                          std::string(e.what()).substr(e.field().size() + 1));
      }
    }
  }

 private:
  std::string prefix_;
};

}  // namespace internal

/// Validates options (nested structs first, then the struct's own Check()).
/// Throws OptionError naming the dotted field path.
template <class Options>
void CheckOptions(const Options& options) {
  internal::CheckVisitor visitor("");
  const_cast<Options&>(options).VisitFields(visitor);
  internal::CheckIfAvailable(options);
}

/// Reads options from a YAML map without validating them: keys absent keep
/// their defaults, unknown keys are rejected. For callers that still apply
/// overrides (command-line flags) before CheckOptions.
template <class Options>
Options ReadOptions(const YAML::Node& node, const std::string& source,
                    const std::string& prefix = "") {
  Options options;
  if (node.IsDefined() && !node.IsNull()) {
    if (!node.IsMap()) {
      throw InputError(
          InputErrorKind::kBadValue, source, node.Mark().line + 1,
          "expected a map of options" + (prefix.empty() ? "" : " under '" + prefix + "'"));
    }
    internal::ReadVisitor visitor(node, source, prefix.empty() ? "" : prefix + ".");
    options.VisitFields(visitor);
    visitor.RejectUnknownKeys();
  }
  return options;
}

/// Reads options from a YAML map; keys absent keep their defaults, unknown
/// keys are rejected, then CheckOptions. `source` names the file for errors.
template <class Options>
Options LoadOptions(const YAML::Node& node, const std::string& source,
                    const std::string& prefix = "") {
  Options options = ReadOptions<Options>(node, source, prefix);
  try {
    CheckOptions(options);
  } catch (const OptionError& e) {
    throw InputError(InputErrorKind::kBadValue, source, 0,
                     (prefix.empty() ? "" : prefix + ".") + std::string(e.what()));
  }
  return options;
}

/// Loads the YAML file at `path` and reads options from its top level, or
/// from the map under `section` when given. Throws InputError on a missing
/// file, YAML syntax error, unknown key or invalid value.
YAML::Node LoadYamlFile(const std::string& path);

template <class Options>
Options LoadOptionsFile(const std::string& path, const std::string& section = "") {
  const YAML::Node root = LoadYamlFile(path);
  return LoadOptions<Options>(section.empty() ? root : root[section], path, section);
}

/// The options as a YAML node (effective values, after defaults).
template <class Options>
YAML::Node OptionsToYaml(const Options& options) {
  YAML::Node node(YAML::NodeType::Map);
  internal::WriteVisitor visitor(&node);
  const_cast<Options&>(options).VisitFields(visitor);
  return node;
}

/// The options as block YAML text, for logging the effective configuration.
template <class Options>
std::string OptionsToString(const Options& options) {
  YAML::Emitter out;
  out << OptionsToYaml(options);
  return out.c_str();
}

}  // namespace ag
