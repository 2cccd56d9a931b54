#include "common/config/options.h"

#include <fstream>

namespace ag {

YAML::Node LoadYamlFile(const std::string& path) {
  std::ifstream probe(path);
  if (!probe) throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot open YAML file");
  try {
    return YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw InputError(InputErrorKind::kMalformedRow, path, e.mark.line + 1, e.msg);
  }
}

}  // namespace ag
