#!/usr/bin/env bash
# Installs what is missing (Debian packages, the glTF validator from npm) and builds lodforge.
# Idempotent: a second run installs nothing and rebuilds only what changed.
#   BUILD_DIR   build folder (default: build)
#   BUILD_TYPE  CMake build type (default: Release)
set -euo pipefail
cd "$(dirname "$0")/.."

BUILD_DIR=${BUILD_DIR:-build}
BUILD_TYPE=${BUILD_TYPE:-Release}
PACKAGES=(cmake g++ ninja-build pkg-config libtbb-dev libeigen3-dev libopenmesh-dev libtinygltf-dev
          nlohmann-json3-dev libgtest-dev libgmock-dev libbenchmark-dev libmeshoptimizer-dev libcli11-dev libstb-dev)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
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

JOBS=${JOBS:-$(nproc)}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE="$BUILD_TYPE" >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS"
