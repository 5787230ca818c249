#!/usr/bin/env bash
# Sets up (installs what is missing, builds) and runs the main job on the bundled sample library: every asset of
# samples/library gets its LOD chain as configs/default.json says, into out/ (LOD files mirroring the library's
# folders, out/report.json and out/report.html). A second run is incremental: unchanged assets are cache hits.
# Extra arguments go to `lodforge run` (e.g. --jobs 4, --force). The library is written by `lodforge demo` when
# the folder holds no assets yet.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
BUILD_DIR=${BUILD_DIR:-build}
if [ -z "$(find samples/library -type f 2>/dev/null | head -n 1)" ]; then
  "$BUILD_DIR/lodforge" demo samples/library
fi
exec "$BUILD_DIR/lodforge" run --config configs/default.json --input samples/library --output out/ "$@"
