#!/usr/bin/env bash
# Photometric stereo on measured reflectance: the simulated shiny sphere on
# the 96-LED dome painted with each measured BRDF table in DIR (MERL .binary
# or EPFL RGL .bsdf; bring your own, the project ships none), every method
# solved once, as photorig-ps-chart --materials does it (docs/photometric-
# stereo-accuracy.md, "Measured materials").
#
#   scripts/benchmark-ps-materials.sh DIR
#
# Writes $OUT/ps_materials.csv (OUT defaults to docs/charts), prints the
# table with each material's best single method and `auto` against it, and
# draws ps_materials.png beside it. About 10 s a table on two cores.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -ne 1 ] || [ ! -d "$1" ]; then
  echo "usage: scripts/benchmark-ps-materials.sh DIR   (DIR: MERL .binary or RGL .bsdf tables)" >&2
  exit 2
fi
chart="${BUILD_DIR:-build}/bin/photorig-ps-chart"
[ -x "$chart" ] || { echo "benchmark-ps-materials: $chart not built (make build)" >&2; exit 2; }
tables=()
for table in "$1"/*.binary "$1"/*.bsdf; do [ -f "$table" ] && tables+=("$table"); done
[ ${#tables[@]} -gt 0 ] || { echo "benchmark-ps-materials: no .binary or .bsdf table in $1" >&2; exit 2; }
out=${OUT:-docs/charts}
mkdir -p "$out"
"$chart" . --materials "$out/ps_materials.csv" "${tables[@]}"
/usr/bin/python3 scripts/charts/ps_materials.py "$out/ps_materials.csv" "$out"
