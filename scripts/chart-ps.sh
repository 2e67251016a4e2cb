#!/usr/bin/env bash
# Photometric stereo: every method on the simulated scenes (and any DiLiGenT
# folders given as arguments) -> docs/charts/ps_results.csv, and on the shiny
# sphere with what a real capture adds -> docs/charts/ps_realistic.csv; both
# drawn as ps_*.png.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
"$build_dir/bin/photorig-ps-chart" . docs/charts/ps_results.csv "$@"
"$build_dir/bin/photorig-ps-chart" . --realistic docs/charts/ps_realistic.csv
/usr/bin/python3 scripts/charts/ps.py docs/charts/ps_results.csv docs/charts
