#!/usr/bin/env bash
# Sets up (installs what is missing, builds) and runs the main job on the bundled sample library.
# Until the batch runner lands, the main job is `lodforge info` over samples/library: every asset is loaded,
# validated and summarised.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
BUILD_DIR=${BUILD_DIR:-build}
exec "$BUILD_DIR/lodforge" info samples/library "$@"
