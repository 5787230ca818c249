#!/usr/bin/env bash
# Builds the libFuzzer harnesses (tests/fuzz) in the ASan + UBSan build (setup.sh SANITIZE=1) and runs them.
#   scripts/fuzz.sh TARGET SECONDS   TARGET: obj ply off stl gltf glb config glob, or all (every one in turn)
# A run of one harness: first every input of tests/fuzz/regressions/TARGET once (each must pass) and of
# tests/fuzz/open/TARGET (known defects, reported), then fuzzing for SECONDS, which starts by running every seed
# (tests/fuzz/seeds/TARGET, plus configs/ for config) and the corpus earlier runs grew (BUILD/fuzz/corpus/TARGET).
# A crash leaves its input in BUILD/fuzz/crashes/TARGET and the run fails; docs/fuzzing.md says how to reproduce
# it and keep it as a regression.
#   SANITIZE_BUILD_DIR  the build folder (default: build-asan)
#   FUZZ_PARALLEL       harnesses run at once by "all" (default: 1)
# Skips with a message (exit 0) where clang and its libFuzzer runtime cannot be installed.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh

ALL_TARGETS=(obj ply off stl gltf glb config glob)
BUILD=${SANITIZE_BUILD_DIR:-build-asan}
FUZZ_PARALLEL=${FUZZ_PARALLEL:-1}

usage() {
  echo "usage: scripts/fuzz.sh TARGET SECONDS   (TARGET: ${ALL_TARGETS[*]} or all)" >&2
  exit 2
}
[ $# -eq 2 ] || usage
[[ $2 =~ ^[0-9]+$ ]] || usage
if [ "$1" = all ]; then
  targets=("${ALL_TARGETS[@]}")
elif [[ " ${ALL_TARGETS[*]} " == *" $1 "* ]]; then
  targets=("$1")
else
  usage
fi
seconds=$2

install_packages clang libclang-rt-dev || echo "fuzz: warning: could not install clang libclang-rt-dev"
if ! clang_has_libfuzzer; then
  echo "fuzz: skipped: clang++ with the libFuzzer runtime is not available (Debian packages clang libclang-rt-dev)"
  exit 0
fi
SANITIZE=1 SANITIZE_BUILD_DIR="$BUILD" TARGETS="${targets[*]/#/fuzz_}" scripts/setup.sh

# The glTF and config harnesses write each input to a file (their readers take paths): in memory where /dev/shm
# is writable, in a folder removed at the end with what crashed harnesses left in it.
scratch_parent=/dev/shm
[ -w "$scratch_parent" ] || scratch_parent=${TMPDIR:-/tmp}
TMPDIR=$(mktemp -d "$scratch_parent/lodforge-fuzz.XXXXXX")
export TMPDIR
trap 'rm -rf "$TMPDIR"' EXIT
# Sanitizer reports name the source line and stop the process at the first one.
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:suppressions=$PWD/tests/sanitize/ubsan.supp}

# Where an input fails: the exception type (if one escaped) and the first frame in lodforge's sources. Two
# crashes with the same signature are taken for the same defect.
signature() {
  local out
  out=$("$1" "$2" 2>&1 || true)
  local exception frame
  exception=$(sed -n "s/^terminate called after throwing an instance of '\(.*\)'$/\1/p" <<<"$out" | head -n 1)
  frame=$(grep -m 1 -oE 'src/[a-z_]+/[A-Za-z0-9_.]+:[0-9]+' <<<"$out" || true)
  if [ -n "$frame" ]; then echo "${exception:+$exception at }$frame"; fi
}

# Whether the first argument is one of the others.
is_known() {
  local sig=$1 k
  shift
  for k in "$@"; do [ "$k" = "$sig" ] && return 0; done
  return 1
}

# Runs one harness; prints one summary line, or the end of its log on failure.
fuzz_one() {
  local target=$1 bin="$BUILD/tests/fuzz/fuzz_$1" dir="$BUILD/fuzz"
  local log="$dir/logs/$target.log" corpus="$dir/corpus/$target" crashes="$dir/crashes/$target/"
  mkdir -p "$dir/logs" "$corpus" "$crashes"
  : >"$log"
  local f
  for f in tests/fuzz/regressions/"$target"/*; do
    [ -e "$f" ] || continue
    if ! "$bin" "$f" >>"$log" 2>&1; then
      echo "fuzz $target: FAILED on the regression input $f; log: $log"
      tail -n 40 "$log"
      return 1
    fi
  done
  # Defects reported but not fixed yet: a fuzzing crash with the same signature is not a new finding.
  local known=()
  for f in tests/fuzz/open/"$target"/*; do
    [ -e "$f" ] || continue
    if "$bin" "$f" >>"$log" 2>&1; then
      echo "fuzz $target: $f passes now: move it to tests/fuzz/regressions/$target/"
    else
      known+=("$(signature "$bin" "$f")")
    fi
  done

  local seeds=(tests/fuzz/seeds/"$target")
  [ "$target" = config ] && seeds+=(configs configs/examples)
  local dict=()
  case $target in
    gltf | glb) dict=(-dict=tests/fuzz/dict/gltf.dict) ;;
    obj | ply | config) dict=(-dict=tests/fuzz/dict/$target.dict) ;;
  esac
  # -timeout: an input that takes seconds is a hang (the readers are linear); -rss_limit_mb: libFuzzer's default.
  # A known defect stops libFuzzer too: fuzzing then goes on from the corpus until the time is up.
  local end=$((SECONDS + seconds)) left crash sig
  while left=$((end - SECONDS)) && [ "$left" -gt 0 ]; do
    if "$bin" "$corpus" "${seeds[@]}" "${dict[@]}" -max_total_time="$left" -timeout=10 -rss_limit_mb=2048 \
         -artifact_prefix="$crashes" -print_final_stats=1 >>"$log" 2>&1; then
      break
    fi
    crash=$(ls -t "$crashes" | head -n 1)
    sig=""
    [ -n "$crash" ] && sig=$(signature "$bin" "$crashes$crash")
    if [ -n "$sig" ] && is_known "$sig" "${known[@]}"; then
      echo "fuzz $target: hit the known open defect again ($sig), going on"
      rm -f "$crashes$crash"
      continue
    fi
    echo "fuzz $target: FAILED (input saved in $crashes$crash); log: $log"
    tail -n 60 "$log"
    return 1
  done
  local runs cov
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | awk '{ n += $1 } END { print n + 0 }')
  cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+ corp: [^ ]+' "$log" | tail -n 1 || true)
  echo "fuzz $target: ok, $seconds s, $runs runs, $cov"
}

status=0
for ((i = 0; i < ${#targets[@]}; i += FUZZ_PARALLEL)); do
  pids=()
  for t in "${targets[@]:i:FUZZ_PARALLEL}"; do
    fuzz_one "$t" &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p" || status=1; done
done
exit $status
