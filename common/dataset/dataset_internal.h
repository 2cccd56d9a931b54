#pragma once

// Pieces of ag::dataset shared between its .cc files; not public API.

#include <string>
#include <vector>

#include "common/dataset/dataset.h"

namespace ag::internal {

/// ReadGroundTruth that also checks every agent name against `air_agents`
/// (the dataset's air/ folders) when given, reporting the line of the key.
DatasetGroundTruth ReadGroundTruthFor(const std::string& path,
                                      const std::vector<std::string>* air_agents);

/// dataset.yaml: format_version (must be 1), name, description.
struct DatasetInfo {
  int format_version = 1;
  std::string name;
  std::string description;
};
DatasetInfo ReadDatasetInfo(const std::string& path);
void WriteDatasetInfo(const std::string& path, const DatasetInfo& info);

/// The format version this code reads and writes.
constexpr int kFormatVersion = 1;

}  // namespace ag::internal
