#!/usr/bin/env bash
# Regenerates docs/charts/autodiff_*.csv and autodiff_*.png: time per derivative vs number of
# inputs and of outputs, and the accuracy of finite differences vs their step.
# Usage: scripts/chart-autodiff.sh   (BUILD_DIR selects the build tree; default ./build)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
program="$build_dir/bin/photorig-autodiff-chart"
if [ -f "$build_dir/CMakeCache.txt" ]; then
  cmake --build "$build_dir" --target photorig-autodiff-chart -j2
fi
if [ ! -x "$program" ]; then
  echo "error: $program not found; configure and build the project first" >&2
  exit 1
fi
mkdir -p docs/charts
"$program" docs/charts
/usr/bin/python3 scripts/charts/autodiff.py docs/charts
