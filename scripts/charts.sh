#!/usr/bin/env bash
# Produces every speed-vs-accuracy chart in docs/charts/ (each scripts/chart-*.sh is one solver's).
set -euo pipefail
export BUILD_DIR=${1:-${BUILD_DIR:-build}}
cd "$(dirname "$0")/.."
for chart in scripts/chart-*.sh; do
  [ -e "$chart" ] || continue
  echo "== $chart"
  bash "$chart"
done
