#!/usr/bin/env bash
# Normal integration: Poisson (from scratch and with a kept workspace) and
# Frankot-Chellappa on a sphere's disc at 32, 384 and 1024 px (bench_ps
# BM_IntegrateNormals) -> docs/charts/integration.csv and
# integration_error_vs_time.png (RMS depth error against time).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$build_dir/bin/bench_ps" --benchmark_filter=BM_IntegrateNormals --benchmark_format=json >"$work/bench.json"
/usr/bin/python3 - "$work/bench.json" docs/charts/integration.csv <<'PY'
import csv, json, sys
runs = json.load(open(sys.argv[1]))["benchmarks"]
scale = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}
with open(sys.argv[2], "w", newline="") as out:
    writer = csv.writer(out)
    writer.writerow(["side_px", "unknowns", "method", "time_ms", "rms_error_px"])
    for run in runs:
        side = run["name"].split("side:")[1].split("/")[0]
        writer.writerow([side, int(run["unknowns"]), run["label"], run["real_time"] * scale[run["time_unit"]],
                         run["rms_error_px"]])
PY
/usr/bin/python3 scripts/charts/integration.py docs/charts/integration.csv docs/charts
