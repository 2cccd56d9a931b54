#include "common/features/global_descriptor.h"

#include <stdexcept>

#include "common/config/options.h"
#include "common/features/onnx_global_descriptor.h"
#include "common/features/vlad.h"

namespace ag {

std::unique_ptr<GlobalDescriptorExtractor> CreateGlobalDescriptorExtractor(
    const GlobalDescriptorOptions& options, const std::string& local_descriptor_type) {
  CheckOptions(options);
  if (options.backend == "onnx") return std::make_unique<OnnxGlobalDescriptor>(options.onnx);

  const std::string& path = local_descriptor_type == "xfeat"  ? options.vlad_codebook_xfeat
                            : local_descriptor_type == "sift" ? options.vlad_codebook_sift
                                                              : std::string();
  if (path.empty()) {
    return std::make_unique<VladExtractor>(BuiltinVladCodebook(local_descriptor_type));
  }
  VladCodebook codebook = ReadVladCodebook(path);  // InputError names the file
  if (codebook.descriptor_type != local_descriptor_type) {
    throw std::runtime_error("VLAD codebook '" + path + "' is for '" + codebook.descriptor_type +
                             "' descriptors, the local features are '" + local_descriptor_type +
                             "'");
  }
  return std::make_unique<VladExtractor>(std::move(codebook));
}

}  // namespace ag
