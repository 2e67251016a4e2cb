#!/usr/bin/env bash
# Regenerates docs/charts/camera_calibration.csv and camera_error_vs_time.png: checkerboard lens
# calibration of three simulated lenses, each distortion model fixed and chosen, error on the
# sample plane against the time of the calibration.
# Usage: scripts/chart-camera.sh   (BUILD_DIR selects the build tree; default ./build)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
program="$build_dir/bin/photorig-camera-chart"
if [ -f "$build_dir/CMakeCache.txt" ]; then
  cmake --build "$build_dir" --target photorig-camera-chart -j2
fi
if [ ! -x "$program" ]; then
  echo "error: $program not found; configure and build the project first" >&2
  exit 1
fi
mkdir -p docs/charts
"$program" docs/charts
/usr/bin/python3 scripts/charts/camera.py docs/charts
