#!/usr/bin/env bash
# Spatially varying reflectance: held-out relighting error against fit time for
# each method, and the per-material fit's reflectance error against time, on
# the simulated three-material scene at four sizes -> docs/charts/reflectance.csv,
# drawn as docs/charts/reflectance_error_vs_time.png.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
"$build_dir/bin/photorig-reflectance-chart" docs/charts/reflectance.csv
/usr/bin/python3 scripts/charts/reflectance.py docs/charts
