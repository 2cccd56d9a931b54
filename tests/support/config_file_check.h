#pragma once

// Checks that a documented configuration file (config/<daemon>.yaml) lists
// every option of an Options struct, each with a comment, at its default
// value: the daemons' --help points users at these files, so they must not
// drift from the code.

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "common/config/options.h"

namespace ag::test {

/// Dotted paths of the map keys under `node` (lists are values, not maps).
inline void CollectKeys(const YAML::Node& node, const std::string& prefix,
                        std::vector<std::string>* keys) {
  if (!node.IsMap()) return;
  for (const auto& kv : node) {
    const std::string key = prefix + kv.first.as<std::string>();
    keys->push_back(key);
    CollectKeys(kv.second, key + ".", keys);
  }
}

/// Lines "key:" of the file that have no comment line right above them
/// (at the same indentation), as "line N: key".
inline std::vector<std::string> UncommentedKeys(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  const std::regex key_line(R"(^( *)([a-z0-9_]+):)");
  std::vector<std::string> missing;
  for (size_t i = 0; i < lines.size(); ++i) {
    std::smatch m;
    if (!std::regex_search(lines[i], m, key_line)) continue;
    const std::string comment_start = m[1].str() + "#";
    if (i == 0 || lines[i - 1].rfind(comment_start, 0) != 0) {
      missing.push_back("line " + std::to_string(i + 1) + ": " + m[2].str());
    }
  }
  return missing;
}

/// The whole check, with failures naming the file and keys.
template <class Options>
void ExpectConfigFileDocumentsDefaults(const std::string& path) {
  SCOPED_TRACE(path);
  // Reading rejects unknown (misspelled) keys, naming file and line. Not
  // validated: a required option (calibration_file) is empty by default.
  Options loaded;
  try {
    loaded = ReadOptions<Options>(LoadYamlFile(path), path);
  } catch (const std::exception& e) {
    FAIL() << e.what();
  }
  // Every value is the default.
  EXPECT_EQ(OptionsToString(loaded), OptionsToString(Options{}))
      << "the file's values differ from the struct defaults";
  // Every option is in the file.
  std::vector<std::string> expected, present;
  CollectKeys(OptionsToYaml(Options{}), "", &expected);
  CollectKeys(LoadYamlFile(path), "", &present);
  for (const std::string& key : expected) {
    EXPECT_NE(std::find(present.begin(), present.end(), key), present.end())
        << "option '" << key << "' is not documented in " << path;
  }
  // And each says what it is.
  for (const std::string& where : UncommentedKeys(path)) {
    ADD_FAILURE() << path << " " << where << " has no comment line above it";
  }
}

}  // namespace ag::test
