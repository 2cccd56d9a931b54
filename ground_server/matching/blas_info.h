#pragma once

// Which BLAS the process runs descriptor matching on. The matcher's matrix
// product goes through OpenCV to the system BLAS (libblas.so.3, chosen by
// Debian's alternatives), and which one that is sets most of the matching
// time: a 1024 x 1024 match takes 4.6 ms with OpenBLAS and 11.7 ms with
// ATLAS, which libceres3 pulls in (tools/bench/match_bench; tools/evaluation/ACCURACY.md,
// "Time per estimate").

#include <string>

namespace ag {

struct BlasInfo {
  /// The library that provides cblas_sgemm to this process; empty when none is
  /// loaded (OpenCV then multiplies with its own code).
  std::string library;
  /// A warning for a BLAS known to be slow, naming the package to install;
  /// empty otherwise.
  std::string warning;
};

/// Looks up the loaded BLAS (dlsym / dladdr, no link-time dependency).
BlasInfo LoadedBlas();

/// Logs LoadedBlas() at start-up: the library (info) and any warning.
void LogLoadedBlas();

/// The warning LoadedBlas() gives for a library path: ATLAS and the
/// reference BLAS are slow, anything else (OpenBLAS, BLIS, MKL) is not.
std::string BlasWarning(const std::string& library);

}  // namespace ag
