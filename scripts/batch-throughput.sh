#!/usr/bin/env bash
# Throughput of `photorig batch solve --local N` (docs/scaling.md): captures
# RUNS simulated runs of RECIPE once, then solves them all with N = 1, 2, ...
# processes, each from scratch, and prints runs per second.
#   scripts/batch-throughput.sh [BUILD_DIR] [RUNS] [RECIPE] [METHOD] [N...]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
runs=${2:-16}
recipe=${3:-config/recipes/ps-sphere.yaml}
method=${4:-auto}
shift $(( $# < 4 ? $# : 4 ))
processes=("$@")
[ ${#processes[@]} -gt 0 ] || processes=(1 2)
photorig="$build/bin/photorig"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for i in $(seq -w 1 "$runs"); do
  "$photorig" run "$recipe" --out "$work/runs/$i" --no-solve > /dev/null 2>&1
done
echo "$runs runs of $recipe, method $method, $(nproc) cores"
for n in "${processes[@]}"; do
  rm -rf "$work"/runs/*/results "$work/batch-$n"
  /usr/bin/python3 - "$photorig" "$work" "$n" "$method" <<'PY'
import json, subprocess, sys
photorig, work, n, method = sys.argv[1:]
out = subprocess.run([photorig, "batch", "solve", "--runs", f"{work}/runs/*", "--local", n, "--method", method,
                      "--batch", f"{work}/batch-{n}", "--json"], capture_output=True, text=True)
doc = json.loads(out.stdout)
tasks = len(doc["tasks"])
print(f"--local {n}: {tasks} runs in {doc['elapsed_s']:.2f} s = {tasks / doc['elapsed_s']:.2f} runs/s"
      f" ({doc['counts']})")
PY
done
