#!/usr/bin/env bash
# Regenerates docs/charts/color_models.csv and color_speed_accuracy.png: fit + leave-one-out
# time against held-out CIEDE2000 for every colour model on every camera (simulated D65
# captures), with OpenCV's 3x3 ColorCorrectionModel beside them.
# Usage: scripts/chart-color.sh   (BUILD_DIR selects the build tree; default ./build)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
targets=(color_model_sweep photorig-color-opencv-ccm)
if [ -f "$build_dir/CMakeCache.txt" ]; then
  cmake --build "$build_dir" --target "${targets[@]}" -j2
fi
for t in "${targets[@]}"; do
  if [ ! -x "$build_dir/bin/$t" ]; then
    echo "error: $build_dir/bin/$t not found; configure and build the project first" >&2
    exit 1
  fi
done
mkdir -p docs/charts
{
  "$build_dir/bin/color_model_sweep" "$build_dir/bin/photorig-color-opencv-ccm" --loss xyz
  "$build_dir/bin/color_model_sweep" "$build_dir/bin/photorig-color-opencv-ccm" --loss ciede2000 | tail -n +2 | grep -v opencv-3x3
} > docs/charts/color_models.csv
/usr/bin/python3 scripts/charts/color.py docs/charts
