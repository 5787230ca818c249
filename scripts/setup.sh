#!/usr/bin/env bash
# Installs what is missing (Debian packages, the glTF validator and the MSFT_lod client check's packages from
# npm, Chromium, Slurm and munge for the cluster test) and builds lodforge.
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

# ---- Browser checks: headless Chromium driven by puppeteer-core (npm) ----
# Used by the report.html browser test, `scripts/bench.sh report` and the MSFT_lod client test (Babylon.js,
# tests/client/msft_lod_client.mjs). Optional: each skips with a message without node, these packages or Chromium.
PUPPETEER_VERSION=25.16.0
BABYLON_VERSION=9.28.0
if command -v npm >/dev/null 2>&1; then
  browser_missing=()
  for spec in "puppeteer-core@$PUPPETEER_VERSION" "babylonjs@$BABYLON_VERSION" "babylonjs-loaders@$BABYLON_VERSION"; do
    pkg=${spec%@*}
    if [ ! -f "tools/node/node_modules/$pkg/package.json" ] ||
       ! grep -q "\"version\": \"${spec##*@}\"" "tools/node/node_modules/$pkg/package.json"; then
      browser_missing+=("$spec")
    fi
  done
  if [ ${#browser_missing[@]} -gt 0 ]; then
    echo "setup: installing ${browser_missing[*]} into tools/node"
    mkdir -p tools/node
    npm install --silent --no-audit --no-fund --prefix tools/node "${browser_missing[@]}" >/dev/null 2>&1 ||
      echo "setup: warning: npm install of ${browser_missing[*]} failed; the browser checks will be skipped"
  fi
fi
if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1; then
  install_packages chromium ||
    echo "setup: warning: could not install chromium; the browser checks will be skipped"
fi
# ---- end of the browser checks ----

# The Slurm round trip (tests/cluster/slurm_roundtrip.sh, docs/cluster.md) starts its own munged, slurmctld and
# slurmd from these packages, never their system services. Optional: the test skips with a message without them.
install_packages slurm-wlm munge ||
  echo "setup: warning: could not install slurm-wlm and munge; the Slurm round trip will be skipped"

JOBS=${JOBS:-$(nproc)}
read -r -a targets <<< "${TARGETS:-}"
cmake -S . -B "$BUILD_DIR" -G Ninja "${cmake_options[@]}" >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" ${targets[@]:+--target "${targets[@]}"}
