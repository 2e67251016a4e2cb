#!/usr/bin/env bash
# Runs every Google Benchmark binary and keeps the JSON beside the console output.
# Figures in docs/performance.md are ratios between benchmarks of one run.
set -euo pipefail
build_dir=${1:-build}
out_dir=${BENCH_OUT:-$build_dir/bench-results}
mkdir -p "$out_dir"
# Spinning OpenMP threads collapse when another process shares the two cores.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
for bench in "$build_dir"/bin/bench_*; do
  name=$(basename "$bench")
  echo "== $name"
  "$bench" --benchmark_min_time=1 --benchmark_out="$out_dir/$name.json" --benchmark_out_format=json
done
