#include "ground_server/matching/blas_info.h"

#include <dlfcn.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <system_error>

namespace ag {

std::string BlasWarning(const std::string& library) {
  std::string kind;
  if (library.find("atlas") != std::string::npos) {
    kind = "ATLAS";
  } else if (library.find("/blas/") != std::string::npos) {
    kind = "the reference BLAS";
  } else {
    return {};
  }
  return "descriptor matching uses " + kind + " (" + library +
         "), which is slower than OpenBLAS (ATLAS takes 2.5x as long for 1024 x 1024 "
         "keypoints): install libopenblas0-serial (tools/setup.sh does) or select it with "
         "update-alternatives --config libblas.so.3-$(gcc -dumpmachine)";
}

BlasInfo LoadedBlas() {
  BlasInfo info;
  // OpenCV's GEMM calls cblas_sgemm.
  void* sgemm = dlsym(RTLD_DEFAULT, "cblas_sgemm");
  Dl_info where{};
  if (sgemm != nullptr && dladdr(sgemm, &where) != 0 && where.dli_fname != nullptr) {
    // The loader's path is Debian's alternatives link; where it leads names
    // the implementation (.../openblas-serial/libblas.so.3).
    std::error_code error;
    const std::filesystem::path real = std::filesystem::canonical(where.dli_fname, error);
    info.library = error ? std::string(where.dli_fname) : real.string();
  }
  info.warning = BlasWarning(info.library);
  return info;
}

void LogLoadedBlas() {
  const BlasInfo blas = LoadedBlas();
  spdlog::info("BLAS for descriptor matching: {}",
               blas.library.empty() ? "none (OpenCV's own product)" : blas.library);
  if (!blas.warning.empty()) spdlog::warn("{}", blas.warning);
}

}  // namespace ag
