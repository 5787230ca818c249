#!/usr/bin/env bash
# Installs what is missing (Debian packages, the glTF validator from npm) and builds lodforge.
# Idempotent: a second run installs nothing and rebuilds only what changed.
#   BUILD_DIR   build folder (default: build)
#   BUILD_TYPE  CMake build type (default: Release)
#   TARGETS     the targets to build, space-separated (default: all)
#   SANITIZE    1: the instrumented build instead (docs/fuzzing.md), into SANITIZE_BUILD_DIR (default build-asan):
#               ASan + UBSan at -O1 with asserts on, by clang with libFuzzer's coverage hooks and the fuzz
#               harnesses (clang and its runtimes are installed if missing), or by g++ where that fails
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh

BUILD_DIR=${BUILD_DIR:-build}
BUILD_TYPE=${BUILD_TYPE:-Release}
PACKAGES=(cmake g++ ninja-build pkg-config libtbb-dev libeigen3-dev libopenmesh-dev libtinygltf-dev
          nlohmann-json3-dev libgtest-dev libgmock-dev libbenchmark-dev libmeshoptimizer-dev libcli11-dev libstb-dev)

install_packages "${PACKAGES[@]}"

cmake_options=(-DCMAKE_BUILD_TYPE="$BUILD_TYPE")
if [ "${SANITIZE:-0}" = 1 ]; then
  BUILD_DIR=${SANITIZE_BUILD_DIR:-build-asan}
  install_packages clang libclang-rt-dev || echo "setup: warning: could not install clang libclang-rt-dev"
  # One build for the sanitizer tests and the fuzzers: the parts compile once for both.
  cmake_options=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g" -DLODFORGE_BUILD_BENCH=OFF)
  if clang_has_libfuzzer; then
    cmake_options+=(-DCMAKE_CXX_COMPILER=clang++ -DLODFORGE_BUILD_FUZZ=ON)
  else
    echo "setup: clang++ with the libFuzzer runtime is not available: sanitizer build with g++, without fuzzers"
    cmake_options+=(-DLODFORGE_SANITIZE=ON)
  fi
fi

# The Khronos glTF validator (npm), used by the tests on written files. Optional: tests skip without node.
VALIDATOR_VERSION=2.0.0-dev.3.10
if command -v npm >/dev/null 2>&1; then
  if [ ! -f tools/node/node_modules/gltf-validator/package.json ] ||
     ! grep -q "\"version\": \"$VALIDATOR_VERSION\"" tools/node/node_modules/gltf-validator/package.json; then
    echo "setup: installing gltf-validator@$VALIDATOR_VERSION into tools/node"
    mkdir -p tools/node
    npm install --silent --no-audit --no-fund --prefix tools/node "gltf-validator@$VALIDATOR_VERSION" >/dev/null 2>&1 ||
      echo "setup: warning: npm install of gltf-validator failed; validator tests will be skipped"
  fi
else
  echo "setup: npm not found; glTF validator tests will be skipped"
fi

# puppeteer-core (npm), which drives the Debian chromium for the report.html browser test and
# `scripts/bench.sh report`. Optional: those skip without it. Kept apart from the validator block above.
PUPPETEER_VERSION=23.11.1
if command -v npm >/dev/null 2>&1; then
  if [ ! -f tools/node/node_modules/puppeteer-core/package.json ] ||
     ! grep -q "\"version\": \"$PUPPETEER_VERSION\"" tools/node/node_modules/puppeteer-core/package.json; then
    echo "setup: installing puppeteer-core@$PUPPETEER_VERSION into tools/node"
    mkdir -p tools/node
    npm install --silent --no-audit --no-fund --prefix tools/node "puppeteer-core@$PUPPETEER_VERSION" >/dev/null 2>&1 ||
      echo "setup: warning: npm install of puppeteer-core failed; report.html browser checks will be skipped"
  fi
fi
if ! command -v chromium >/dev/null 2>&1; then
  echo "setup: chromium not found (apt-get install chromium); report.html browser checks will be skipped"
fi

JOBS=${JOBS:-$(nproc)}
read -r -a targets <<< "${TARGETS:-}"
cmake -S . -B "$BUILD_DIR" -G Ninja "${cmake_options[@]}" >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" ${targets[@]:+--target "${targets[@]}"}
