#!/usr/bin/env bash
# BRDF fits: fit error against fit time for every model on synthetic
# gonioreflectometer measurements of three materials -> docs/charts/brdf_fits.csv,
# drawn as docs/charts/brdf_fit_error_vs_time.png.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
"$build_dir/bin/photorig-brdf-chart" docs/charts/brdf_fits.csv
/usr/bin/python3 scripts/charts/brdf.py docs/charts
