#!/usr/bin/env bash
# Sets up (installs what is missing, builds) and runs every test under ctest. Non-zero exit on any failure.
# Tests that need ../shared/corpus skip with a message when it is absent.
#   scripts/test.sh [CTEST_ARGS...]                    the normal build (BUILD_DIR, default build)
#   scripts/test.sh --sanitize [CTEST_ARGS...]         every test in the ASan + UBSan build (setup.sh SANITIZE=1,
#                                                      SANITIZE_BUILD_DIR, default build-asan; docs/fuzzing.md)
#   scripts/test.sh --sanitize-subset [CTEST_ARGS...]  the same build, CI's subset of the tests (below)
set -euo pipefail
cd "$(dirname "$0")/.."

# CI's sanitizer subset: the core and batch tests (threads, the flow graph, the cache, reports), which no fuzzer
# reaches, less the five that process a whole library two to four times or the corpus library (each takes
# minutes under ASan). The readers run in CI under the same sanitizers through their fuzzers (scripts/fuzz.sh).
SUBSET_TARGETS=(test_core test_batch)
SUBSET_LABELS='^(core|batch)$'
SUBSET_EXCLUDE='^(BatchCorpus\..*|BatchRunner\.(SameBytesForAnyJobCount|SecondRunIsAllCacheHitsAndTouchingOneFileRedoesOne|ThreeShardsMergeToTheUnshardedReport|StoppedRunResumesToIdenticalOutput))$'

BUILD_DIR=${BUILD_DIR:-build}
case ${1:-} in
  --sanitize)
    shift
    export SANITIZE=1
    BUILD_DIR=${SANITIZE_BUILD_DIR:-build-asan}
    ;;
  --sanitize-subset)
    shift
    export SANITIZE=1 TARGETS="${SUBSET_TARGETS[*]}"
    BUILD_DIR=${SANITIZE_BUILD_DIR:-build-asan}
    set -- -L "$SUBSET_LABELS" -E "$SUBSET_EXCLUDE" "$@"
    ;;
esac
scripts/setup.sh
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$(nproc)" --timeout 600 "$@"
