#!/usr/bin/env bash
# libFuzzer targets for every parser (fuzz/, docs/fuzzing.md), built with clang,
# AddressSanitizer and UndefinedBehaviorSanitizer in their own build tree.
#
#   scripts/fuzz.sh build [TARGET...]       configure and build the fuzzers (only the named ones and the
#                                           libraries they link, if any are named)
#   scripts/fuzz.sh smoke                   build, then run each fuzzer for 1000 inputs from its seeds, with a
#                                           fixed random seed so that a failure repeats; fails on any finding
#   scripts/fuzz.sh run [TARGET] [SECONDS]  long runs (default: every target, 300 s each), corpus kept in
#                                           the build tree; builds only what they need; prints executions
#                                           reached and their rate
#   scripts/fuzz.sh seeds                   build, then rewrite the seeds the targets write themselves
#                                           (fuzz/corpus/<target>/, committed) from the current formats
#   scripts/fuzz.sh list                    the targets
#
# Environment: PHOTORIG_FUZZ_BUILD (build tree, default build-fuzz/), FUZZ_JOBS (build jobs, default 2),
# FUZZ_WORKERS (parallel fuzzing processes per target in `run`, default 2), FUZZ_RUNS (`run` stops each
# worker after this many executions, e.g. 10000000, or at SECONDS, whichever comes first),
# FUZZ_SKIP_BUILD=1 (`run` without building first, e.g. while the tree is being built by another command).
# A finding leaves its input in <build tree>/artifacts/<target>/; replay it with
#   <build tree>/bin/<target> <file>
# and keep it as a test: copy it to fuzz/regressions/<target>/ (CTest's <target>_replay replays it
# in the normal build), then fix the parser.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${PHOTORIG_FUZZ_BUILD:-$root/build-fuzz}"
jobs="${FUZZ_JOBS:-2}"
workers="${FUZZ_WORKERS:-2}"
log_root="$build/logs"
targets=(fuzz_rig fuzz_recipe fuzz_diligent fuzz_run_store fuzz_manifest fuzz_image_decode fuzz_color_model fuzz_light_files fuzz_api
         fuzz_merl fuzz_rgl_tensor fuzz_gltf_roundtrip)
# Limits of every run: a finding is a crash, a sanitizer report, an escaped
# exception, more than 2 GiB of memory or one input taking more than 10 s.
limits=(-rss_limit_mb=2048 -timeout=10)
# AddressSanitizer keeps freed memory in quarantine to catch use-after-free;
# with images decoded and freed at every input its default lets the
# quarantine alone pass the 2 GiB limit. 64 MiB still catches recent reuse.
# It also records every allocation's stack, a sixth of the API and glTF
# targets' time: one frame is kept (a report still shows the faulting
# access's whole stack; replaying a finding without these options shows
# the allocation's too).
export ASAN_OPTIONS="${ASAN_OPTIONS:-quarantine_size_mb=64:malloc_context_size=1}"

die() {
  echo "fuzz: $*" >&2
  exit 1
}

need_clang() {
  command -v clang++ >/dev/null 2>&1 || die "clang++ not found: run scripts/install-deps.sh (clang, libclang-rt-14-dev)"
  local fuzzer_lib
  fuzzer_lib="$(clang++ -print-file-name=libclang_rt.fuzzer-x86_64.a 2>/dev/null || true)"
  if [ ! -f "$fuzzer_lib" ]; then
    fuzzer_lib="$(find "$(clang++ -print-resource-dir)" -name 'libclang_rt.fuzzer*.a' 2>/dev/null | head -n1)"
  fi
  [ -n "$fuzzer_lib" ] && [ -f "$fuzzer_lib" ] ||
    die "libFuzzer runtime not found: run scripts/install-deps.sh (libclang-rt-14-dev)"
}

build_fuzzers() {
  need_clang
  local launcher=()
  command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  if [ ! -f "$build/CMakeCache.txt" ]; then
    # -O1 without NDEBUG: assertions stay on (each one a check the fuzzer can trip); RelWithDebInfo
    # also keeps the solvers' Release-only -O3 out, which would lengthen the build.
    CC=clang CXX=clang++ cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 "${launcher[@]}" \
      -DPHOTORIG_FUZZ=ON -DPHOTORIG_BUILD_TESTS=OFF -DPHOTORIG_BUILD_BENCH=OFF >/dev/null
  fi
  # A target links a few of the libraries (fuzz/CMakeLists.txt): the MERL
  # target, for one, needs the BRDF library alone, not the whole tree.
  if [ $# -gt 0 ]; then
    cmake --build "$build" --target "$@" -j "$jobs"
  else
    cmake --build "$build" --target photorig_fuzzers -j "$jobs"
  fi
  # The solvers' parser files are instrumented one by one (fuzz/CMakeLists.txt):
  # a path that names no file there would leave the fuzzers blind without an error.
  local parser
  for parser in solvers/lighting/src/light_files.cpp solvers/color/src/model_io.cpp solvers/color/src/model.cpp \
                solvers/brdf/src/merl.cpp solvers/brdf/src/tensor_file.cpp solvers/brdf/src/rgl.cpp; do
    grep -F -B3 "\"file\": \"$root/$parser\"" "$build/compile_commands.json" | grep -q -- -fsanitize=fuzzer-no-link ||
      die "$parser is not instrumented in $build (fuzz/CMakeLists.txt)"
  done
}

check_target() {
  local t
  for t in "${targets[@]}"; do [ "$t" = "$1" ] && return 0; done
  die "no target '$1' (targets: ${targets[*]})"
}

# Targets whose seeds they write themselves (PHOTORIG_FUZZ_SEEDS): valid inputs
# made by the formats' own writers.
written_seeds=(fuzz_diligent fuzz_run_store fuzz_color_model fuzz_merl fuzz_rgl_tensor)

write_seeds() {
  local t out
  for t in "${written_seeds[@]}"; do
    out="$root/fuzz/corpus/$t"
    rm -rf "$out"
    mkdir -p "$out"
    PHOTORIG_FUZZ_SEEDS="$out" "$build/bin/$t" -runs=1 >/dev/null 2>&1 || die "$t: writing its seeds failed"
    echo "$t: $(ls "$out" | wc -l) seed(s) in fuzz/corpus/$t/"
  done
}

# Seeds: the committed ones in fuzz/corpus/<target>/, the rigs and recipes of
# config/ (and each recipe as a dry-run request for the API).
make_seeds() {
  local t="$1" out="$build/seeds/$1"
  rm -rf "$out"
  mkdir -p "$out"
  [ -d "$root/fuzz/corpus/$t" ] && cp -r "$root/fuzz/corpus/$t/." "$out/"
  case "$t" in
    # Without their comments: what the parser sees of a rig fits in the
    # targets' input limit (max_len_flag) and the mutator spends no time on prose.
    fuzz_rig | fuzz_recipe)
      local dir=rigs f
      [ "$t" = fuzz_recipe ] && dir=recipes
      for f in "$root/config/$dir"/*.yaml; do
        sed -e 's/[[:space:]]*#.*$//' -e '/^[[:space:]]*$/d' "$f" >"$out/$(basename "$f")"
      done ;;
    fuzz_api)
      local recipe body
      for recipe in "$root"/config/recipes/*.yaml; do
        body="$(cat "$recipe")"
        printf 'POST /api/v1/dry-run HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/yaml\r\nContent-Length: %d\r\n\r\n%s' \
          "$(printf '%s' "$body" | wc -c)" "$body" >"$out/dry-run-$(basename "$recipe" .yaml)"
      done ;;
  esac
}

dict_flag() {
  case "$1" in
    fuzz_rig | fuzz_recipe | fuzz_color_model) echo "-dict=$root/fuzz/yaml.dict" ;;
    fuzz_api) echo "-dict=$root/fuzz/http.dict" ;;
  esac
}

# Inputs longer than this are never tried (libFuzzer's -max_len, whose default
# is the longest seed). A YAML rig, recipe or colour model reaches every key
# and check of its parser within 4 KiB (a rig's LED list only repeats one
# entry); longer inputs cost time in the scanner without new paths.
max_len_flag() {
  case "$1" in
    fuzz_rig | fuzz_recipe | fuzz_color_model) echo "-max_len=4096" ;;
  esac
}

# Runs one target for `seconds` with `n` workers, and any further libFuzzer
# flags; prints "target executions findings".
fuzz_target() {
  local t="$1" seconds="$2" n="$3" corpus="$build/corpus/$1" logs="$log_root/$1" artifacts="$build/artifacts/$1"
  shift 3
  local extra=("$@")
  mkdir -p "$corpus" "$artifacts"
  rm -rf "$logs"
  mkdir -p "$logs"
  make_seeds "$t"
  local status=0 start=$SECONDS runs=()
  [ -n "${FUZZ_RUNS:-}" ] && runs=(-runs="$FUZZ_RUNS")
  # libFuzzer adds new inputs to the first directory only: the seeds stay as they are.
  (cd "$logs" && "$build/bin/$t" "$corpus" "$build/seeds/$t" $(dict_flag "$t") $(max_len_flag "$t") "${limits[@]}" "${runs[@]}" \
    -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="$artifacts/" \
    -jobs="$n" -workers="$n" "${extra[@]}" >"$logs/main.log" 2>&1) || status=$?
  local elapsed=$((SECONDS - start))
  # With -jobs the workers' logs are fuzz-<n>.log (main.log repeats them):
  # executions are summed over them.
  local execs findings
  execs="$(cat "$logs"/fuzz-*.log | awk '/stat::number_of_executed_units/ {s += $2} END {print s + 0}')"
  findings="$(grep -l -E 'ERROR: (AddressSanitizer|UndefinedBehaviorSanitizer|LeakSanitizer|libFuzzer)|runtime error:|uncaught exception|terminate called' "$logs"/fuzz-*.log | wc -l || true)"
  printf '%-20s %12s executions  %8s exec/s  %d finding(s)  (%d s, %d worker(s), corpus %d files)\n' \
    "$t" "$execs" "$((execs / (elapsed > 0 ? elapsed : 1)))" "$findings" "$elapsed" "$n" "$(ls "$corpus" | wc -l)"
  if [ "$status" != 0 ] || [ "$findings" != 0 ]; then
    grep -h -E -A12 'ERROR: |runtime error:|uncaught exception|terminate called|500 answer' "$logs"/*.log | head -n 60 >&2 || true
    echo "fuzz: $t found a problem; inputs in $artifacts/, logs in $logs/" >&2
    failures+=("$t: $(grep -h -m1 -E 'ERROR: |runtime error:|uncaught exception|terminate called' "$logs"/*.log | head -n1)")
    return 1
  fi
}

command="${1:-}"
case "$command" in
  list) printf '%s\n' "${targets[@]}" ;;
  build)
    shift
    for t in "$@"; do check_target "$t"; done
    build_fuzzers "$@" ;;
  seeds)
    build_fuzzers "${written_seeds[@]}"
    write_seeds ;;
  smoke)
    # Logs of their own: a long run in the same tree keeps its logs (and
    # the executions counted from them) while the suite runs.
    log_root="$build/logs/smoke"
    build_fuzzers
    # A fixed seed and a count of inputs rather than a time: the same inputs
    # on every machine, so a finding here repeats where it is looked at. The
    # time limit only guards against a hang.
    failed=0
    failures=()
    for t in "${targets[@]}"; do fuzz_target "$t" 300 1 -seed=1 -runs=1000 || failed=1; done
    # Last, where a log's tail shows it: what failed, and how to repeat it.
    for f in "${failures[@]}"; do echo "fuzz smoke failed: $f" >&2; done
    [ "$failed" = 0 ] || echo "repeat: scripts/fuzz.sh smoke (seed 1, 1000 inputs per target)" >&2
    exit "$failed" ;;
  run)
    selected=("${targets[@]}")
    if [ -n "${2:-}" ] && [ "$2" != all ]; then
      check_target "$2"
      selected=("$2")
    fi
    seconds="${3:-300}"
    [ "${FUZZ_SKIP_BUILD:-0}" = 1 ] || build_fuzzers "${selected[@]}"
    failed=0
    for t in "${selected[@]}"; do fuzz_target "$t" "$seconds" "$workers" || failed=1; done
    exit "$failed" ;;
  *) sed -n '2,22p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2 ;;
esac
