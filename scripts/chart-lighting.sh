#!/usr/bin/env bash
# Regenerates docs/charts/lighting_*.csv and lighting_*.png: mirror-sphere light-direction error
# vs sphere radius and vs noise, the env-map round-trip error vs mirror-ball size, LED positions,
# spherical-harmonic lighting, white-sphere intensities and LED drive weights.
# Usage: scripts/chart-lighting.sh   (BUILD_DIR selects the build tree; default ./build)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
program="$build_dir/bin/photorig-lighting-chart"
if [ -f "$build_dir/CMakeCache.txt" ]; then
  cmake --build "$build_dir" --target photorig-lighting-chart -j2
fi
if [ ! -x "$program" ]; then
  echo "error: $program not found; configure and build the project first" >&2
  exit 1
fi
mkdir -p docs/charts
"$program" docs/charts
/usr/bin/python3 scripts/charts/lighting.py docs/charts
