#pragma once

#include <string>

namespace ag {

/// True for a valid air agent name: one or more of [a-z0-9_] (dataset
/// folder names, LCM channel suffixes and packet fields all use it).
bool IsValidAgentName(const std::string& name);

}  // namespace ag
