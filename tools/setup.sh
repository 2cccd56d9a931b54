#!/usr/bin/env bash
# Installs every Debian package the project needs (only what is missing), then
# configures and builds with CMake into build/ (Release).
#   tools/setup.sh                 # install + build
#   AG_SKIP_INSTALL=1 tools/setup.sh   # build only
#   AG_CMAKE_ARGS="-DAG_SANITIZE_ADDRESS=ON" tools/setup.sh
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake pkg-config ccache git
  libeigen3-dev libopencv-dev libceres-dev libpcl-dev
  liblcm-dev liblcm-bin liblcm-java libjchart2d-java libglib2.0-dev default-jdk-headless
  libspdlog-dev libyaml-cpp-dev libcli11-dev libhnswlib-dev libfaiss-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  # The system BLAS (libblas.so.3) that descriptor matching runs on: libceres3
  # pulls in ATLAS, with which estimates take 1.8x as long ("Time per estimate"
  # in the README). OpenBLAS outranks it in Debian's alternatives; serial, as
  # the estimator runs on one core beside the map thread.
  libopenblas0-serial
  python3-onnx
  iproute2 iptables clang-format clang-tidy
)

install_packages() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    echo "setup: all ${#PACKAGES[@]} Debian packages present"
    return
  fi
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  echo "setup: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

if [ "${AG_SKIP_INSTALL:-0}" != "1" ]; then install_packages; fi

jobs=$(nproc)
cmake_args=(-S . -B build -DCMAKE_BUILD_TYPE=Release)
if [ "${CI:-}" = "true" ]; then cmake_args+=(-DAG_WERROR=ON); fi
# shellcheck disable=SC2206
cmake_args+=(${AG_CMAKE_ARGS:-})
cmake "${cmake_args[@]}"
cmake --build build -j "$jobs"
