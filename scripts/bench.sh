#!/usr/bin/env bash
# Sets up (installs what is missing, builds; see scripts/setup.sh) and runs the benchmarks of tests/bench.
# Benchmarks are never part of the tests: they print numbers and MET / NOT MET lines, and exit 0 whatever they say.
#
#   scripts/bench.sh [ARGS...]            all three benchmarks; ARGS go to lodforge_bench_simplify
#   scripts/bench.sh simplify [ARGS...]   only lodforge_bench_simplify
#   scripts/bench.sh load [ARGS...]       only lodforge_bench_load
#   scripts/bench.sh batch [ARGS...]      only lodforge_bench_batch (the batch targets of issue 5)
#   scripts/bench.sh attributes [ARGS...] only lodforge_bench_attributes (attribute-aware vs position-only lodforge vs
#                                         meshopt on the glTF corpus at 50/25/10%: distance, UV flips, chart spans,
#                                         attribute RMS, throughput; --ratios, --reps N, --eval-samples N, --corpus DIR)
#   scripts/bench.sh eval [ARGS...]       only lodforge_bench_eval (eval on degenerate and sliver-heavy meshes -- a
#                                         fanned 20000-corner zig-zag polygon and friends -- against itself and a
#                                         moved copy, vs a clean grid of the same triangle count: both times, the
#                                         ratio (target <= 10x), BVH work per query; --triangles N, --reps N,
#                                         --samples N, --threads N, --case NAME)
#   scripts/bench.sh quad [ARGS...]       only lodforge_bench_quad (polychord engine vs edge_collapse and meshopt on
#                                         the quad corpus at 50/25/10%, plus a generated 100k-quad torus; --ratios,
#                                         --mesh FILE, --input DIR, --generated-quads N, --no-generated)
#   scripts/bench.sh cluster [ARGS...]    only lodforge_bench_cluster (the vertex clustering engine vs
#                                         meshopt_simplifySloppy at the same triangle count on the scanned corpus and a
#                                         generated fBm terrain: speed on 1 and all threads, RMS and Hausdorff; targets
#                                         speed >= 1.0x, RMS <= 0.8x; --ratios, --terrain-ratios, --terrain-side N
#                                         (2900: 16.8M triangles), --mesh FILE, --no-terrain, --eval-samples N, --reps N)
#   scripts/bench.sh report [ARGS...]     only lodforge_bench_report (report.html for 100 000 assets in headless
#                                         Chromium: load <= 3 s, filter/sort <= 200 ms, <= 1 KB per asset;
#                                         --assets N, --reps N, --out DIR; needs node + puppeteer-core + chromium)
#   scripts/bench.sh tiling [ARGS...]     only lodforge_bench_tiling (tiled vs untiled lodforge vs meshopt_simplify on
#                                         the generated fBm terrain, 2 threads: time, peak memory, RMS/mean error;
#                                         targets tiled <= 0.5x meshopt's time, RMS and mean <= 1.1x untiled; --side N
#                                         (default 1415: 4.0M triangles; 2900: 16.8M), --ratio, --threads, --tile-triangles,
#                                         --eval-samples, --skip-untiled; JSON: $BUILD_DIR/bench/bench-tiling.json)
#   scripts/bench.sh conservative [ARGS...] only lodforge_bench_conservative (conservative LODs, docs/conservative.md:
#                                         bounding volume overhead vs the naive offset hull, occluder silhouettes on
#                                         the closed scanned corpus; --ratio, --raster, --file, --corpus)
#   scripts/bench.sh terrain [ARGS...]   only lodforge_bench_terrain (terrain patch chains, docs/terrain.md: one
#                                         65 x 65 patch's occluder chain on one core vs meshopt_simplify to the
#                                         same counts, all patches of a 1025 x 1025 fBm map; --side, --reps,
#                                         --threads)
#   scripts/bench.sh symmetry [ARGS...]  only lodforge_bench_symmetry --simplify (symmetric simplification,
#                                         docs/symmetry.md: paired fraction, mirror error and mean distance with and
#                                         without symmetry_weight; --weight, --noise, FILES; without --simplify in
#                                         ARGS... the binary times detection instead)
#   scripts/bench.sh budget [ARGS...]     only lodforge_bench_budget (error budgets, docs/budgets.md: the LOD simplify()
#                                         makes with a budget vs its reported bound and the measured Hausdorff, vs
#                                         the longest holding prefix of the same collapse sequence and vs meshopt at
#                                         the same budget; slow: 1-4 minutes per case on 2 cores)
#
# lodforge_bench_budget (scanned and hard-surface corpus, geometry only):
#   --quick                  bunny, fandisk, armadillo-remeshed-29k, wingnut at 0.0005,0.002,0.01
#   --corpus DIR             corpus folder, its scanned/ and hardsurface/ meshes (default: the one the build names)
#   --mesh FILE              run these files instead (repeatable)
#   --budgets 0.0005,...     budgets as fractions of the bounding-box diagonal (default 0.0005,0.002,0.01,0.05)
#   --eval-samples N         area samples per direction measuring the LOD's Hausdorff (default 1000000)
#   --scan-samples N         the same for each prefix of the oracle scan and each meshopt step (default 0: eval's)
#   --coarse-steps N, --fine-steps N   oracle scan strides, log/N (default 64, 512)
#   --meshopt-steps N        bisection steps on meshopt's target count (default 12)
#   --oracle-max-budget F    oracle and meshopt only for budgets up to F (default 0.01)
#
# lodforge_bench_simplify (lodforge vs meshoptimizer vs OpenMesh Decimater: speed, peak memory, quality; lodforge-mc
# is the multiple_choice engine; meshes of 1M triangles and more also run two lodforge-1t processes at once, the
# machine's two-thread ceiling):
#   --quick                  fast subset (bunny, dragon, buddha, lucy; ratios 0.1,0.02,0.01; 500k generated mesh;
#                            300k eval samples; 1 repetition; OpenMesh only up to 150k triangles)
#   --input DIR              folder of meshes (default ../shared/corpus/scanned)
#   --mesh FILE              run these files instead (repeatable)
#   --ratios 0.5,0.1,...     target ratios (default 0.5,0.1,0.02,0.01)
#   --methods a,b            subset of lodforge-1t,lodforge-all,lodforge-mc,meshopt,openmesh
#   --no-generated           skip the generated ~2M-triangle torus (--generated-triangles N to resize it)
#   --no-plate               skip the generated flat CAD-like plate (--plate-triangles N, default 400k; 200k quick)
#   --terrain                add the generated 16.8M-triangle fBm terrain at 1% (minutes; --terrain-side N)
#   --no-ceiling             skip the two-process runs
#   --eval-samples N         area samples per direction for the quality evaluation (default 1000000); --no-eval
#   --reps N, --rep-budget S best of up to N repetitions, fewer once they add up to S seconds (default 3, 1.0)
#   --openmesh-max N         skip the (slow) Decimater on meshes above N triangles (default 1000000)
#   --timeout S              kill one run after S seconds (default 900)
#   --json FILE              JSON report (default here: $BUILD_DIR/bench/bench-simplify.json)
# lodforge_bench_load (load_asset vs OpenMesh IO; Google Benchmark): --corpus=DIR, --file=PATH (repeatable) and
#   every --benchmark_* flag; JSON report: $BUILD_DIR/bench/bench-load.json. With `--quick` in the combined mode
#   the load benchmark runs with --benchmark_min_time=0.1.
#
# lodforge_bench_batch (runs `lodforge run` as a child process): jobs 2 vs jobs 1 on the tests' generated library
#   (target >= 1.8x) and peak RSS under --memory-limit for a library 4x that size. --assets N (200), --reps N (3),
#   --memory-limit SIZE (32M), --memory-asset-triangles N, --memory-jobs J..., --skip-throughput, --skip-memory,
#   --quick (1 repetition).
#   In the combined mode it runs with --quick when --quick is given.
#
# Environment: BUILD_DIR (default build), BUILD_TYPE (default Release), BENCH_SKIP_SETUP=1 to skip setup.sh
# (use an existing build), LOAD_BENCH_ARGS (extra arguments for the load benchmark in the combined mode).
# Timings are only meaningful on an otherwise idle machine; the simplify benchmark prints the load average.
set -euo pipefail
cd "$(dirname "$0")/.."

BUILD_DIR=${BUILD_DIR:-build}
if [ "${BENCH_SKIP_SETUP:-0}" != 1 ]; then
  scripts/setup.sh
fi
SIMPLIFY="$BUILD_DIR/tests/bench/lodforge_bench_simplify"
LOAD="$BUILD_DIR/tests/bench/lodforge_bench_load"
BATCH="$BUILD_DIR/tests/bench/lodforge_bench_batch"
QUAD="$BUILD_DIR/tests/bench/lodforge_bench_quad"
ATTRIBUTES="$BUILD_DIR/tests/bench/lodforge_bench_attributes"
EVAL="$BUILD_DIR/tests/bench/lodforge_bench_eval"
BUDGET="$BUILD_DIR/tests/bench/lodforge_bench_budget"
REPORT="$BUILD_DIR/tests/bench/lodforge_bench_report"
CLUSTER="$BUILD_DIR/tests/bench/lodforge_bench_cluster"
TILING="$BUILD_DIR/tests/bench/lodforge_bench_tiling"
CONSERVATIVE="$BUILD_DIR/tests/bench/lodforge_bench_conservative"
SYMMETRY="$BUILD_DIR/tests/bench/lodforge_bench_symmetry"
TERRAIN="$BUILD_DIR/tests/bench/lodforge_bench_terrain"
mode=all
case "${1:-}" in
  simplify | load | batch | quad | attributes | eval | budget | report | cluster | tiling | conservative | symmetry | terrain) mode=$1; shift ;;
esac
# The binaries this mode runs must be built (the combined mode runs simplify, load and batch).
case $mode in
  all) needed=("$SIMPLIFY" "$LOAD" "$BATCH") ;;
  simplify) needed=("$SIMPLIFY") ;; load) needed=("$LOAD") ;; batch) needed=("$BATCH") ;; quad) needed=("$QUAD") ;;
  attributes) needed=("$ATTRIBUTES") ;; eval) needed=("$EVAL") ;; budget) needed=("$BUDGET") ;; report) needed=("$REPORT") ;;
  cluster) needed=("$CLUSTER") ;; tiling) needed=("$TILING") ;; conservative) needed=("$CONSERVATIVE") ;;
  symmetry) needed=("$SYMMETRY") ;; terrain) needed=("$TERRAIN") ;;
esac
for b in "${needed[@]}"; do
  if [ ! -x "$b" ]; then
    echo "bench: $b is missing (configure with -DLODFORGE_BUILD_BENCH=ON and build)" >&2
    exit 2
  fi
done
OUT_DIR="$BUILD_DIR/bench"
mkdir -p "$OUT_DIR"

run_simplify() {
  local has_json=0
  for a in "$@"; do
    case "$a" in --json | --json=*) has_json=1 ;; esac
  done
  if [ $has_json = 1 ]; then
    "$SIMPLIFY" "$@"
  else
    "$SIMPLIFY" --json "$OUT_DIR/bench-simplify.json" "$@"
  fi
}

run_load() {
  "$LOAD" --benchmark_out="$OUT_DIR/bench-load.json" --benchmark_out_format=json "$@"
}

case $mode in
  simplify) run_simplify "$@" ;;
  load) run_load "$@" ;;
  batch) "$BATCH" "$@" ;;
  quad) "$QUAD" "$@" ;;
  eval) "$EVAL" "$@" ;;
  budget) "$BUDGET" "$@" ;;
  cluster) "$CLUSTER" "$@" ;;
  tiling) "$TILING" --json "$OUT_DIR/bench-tiling.json" "$@" ;;
  conservative) "$CONSERVATIVE" "$@" ;;
  symmetry) "$SYMMETRY" --simplify "$@" ;;
  terrain) "$TERRAIN" "$@" ;;
  report) "$REPORT" --out "$OUT_DIR/report" "$@" ;;
  attributes) "$ATTRIBUTES" --json "$OUT_DIR/bench-attributes.json" "$@" ;;
  all)
    load_args=()
    for a in "$@"; do
      [ "$a" = --quick ] && load_args+=(--benchmark_min_time=0.1)
    done
    # shellcheck disable=SC2206  # LOAD_BENCH_ARGS is a space-separated list on purpose
    [ -n "${LOAD_BENCH_ARGS:-}" ] && load_args+=(${LOAD_BENCH_ARGS})
    echo "== lodforge_bench_simplify =="
    run_simplify "$@"
    echo
    echo "== lodforge_bench_load =="
    run_load "${load_args[@]+"${load_args[@]}"}"
    batch_args=()
    for a in "$@"; do
      [ "$a" = --quick ] && batch_args+=(--quick)
    done
    echo
    echo "== lodforge_bench_batch =="
    "$BATCH" "${batch_args[@]+"${batch_args[@]}"}"
    ;;
esac
