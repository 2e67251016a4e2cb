#!/usr/bin/env bash
# Photometric stereo on real objects: DiLiGenT-layout folders (the benchmark's
# 16-bit originals or the cropped 8-bit copy; bring your own, the project
# ships none), every object under every method, as `photorig solve ps
# --dataset` solves them.
#
#   scripts/benchmark-diligent.sh DIR [OBJECTS] [METHODS]
#
# DIR holds one folder per object (`ballPNG/`, `pot1PNG/`, ...). OBJECTS and
# METHODS are comma-separated (default: every *PNG folder in DIR; every
# method). Writes, per object and method, the mean and median angular error
# against the object's Normal_gt.mat, the pixels left without a normal and
# those filled from their neighbours, and the whole process's wall time, to
# $OUT/diligent.csv (OUT defaults to docs/charts), then prints the table with
# the mean over the objects and draws diligent_error_vs_time.png beside it.
# Runs one solve at a time, so that the times compare.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 1 ] || [ ! -d "$1" ]; then
  echo "usage: scripts/benchmark-diligent.sh DIR [OBJECTS] [METHODS]   (DIR: DiLiGenT-layout object folders)" >&2
  exit 2
fi
data=$1
photorig="${BUILD_DIR:-build}/bin/photorig"
[ -x "$photorig" ] || { echo "benchmark-diligent: $photorig not built (make build)" >&2; exit 2; }
out=${OUT:-docs/charts}
mkdir -p "$out"
if [ -n "${2:-}" ]; then
  IFS=, read -r -a objects <<<"$2"
else
  objects=()
  for folder in "$data"/*PNG; do [ -d "$folder" ] && objects+=("$(basename "$folder" PNG)"); done
fi
[ ${#objects[@]} -gt 0 ] || { echo "benchmark-diligent: no <object>PNG folder in $data" >&2; exit 2; }
IFS=, read -r -a methods <<<"${3:-l2,lambertian,robust,blinn-phong,auto,low-frequency}"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
csv="$out/diligent.csv"
echo "object,method,mean_deg,median_deg,unresolved,filled,filled_mean_deg,wall_s" >"$csv"
for object in "${objects[@]}"; do
  for method in "${methods[@]}"; do
    echo "$object: $method" >&2
    start=$(date +%s.%N)
    status=0
    "$photorig" solve ps --dataset "$data/${object}PNG" --method "$method" --integrator none \
      --out "$work/$object-$method" --json >"$work/$object-$method.json" 2>"$work/$object-$method.log" || status=$?
    end=$(date +%s.%N)
    if [ ! -f "$work/$object-$method/report.json" ]; then
      echo "benchmark-diligent: $object $method wrote no report (exit $status):" >&2
      cat "$work/$object-$method.log" >&2
      exit 1
    fi
    /usr/bin/python3 - "$object" "$method" "$work/$object-$method/report.json" "$start" "$end" >>"$csv" <<'PY'
import json, sys
obj, method, path, start, end = sys.argv[1:]
r = json.load(open(path))
truth = r.get("ground_truth", {})
fill = r.get("fill", {})
filled = truth.get("filled", {})
print(",".join(str(v) for v in [obj, method, truth.get("mean_angular_error_deg", "nan"),
                                truth.get("median_angular_error_deg", "nan"), truth.get("pixels_unresolved", "nan"),
                                fill.get("pixels_filled", 0), filled.get("mean_angular_error_deg", ""),
                                round(float(end) - float(start), 3)]))
PY
  done
done
/usr/bin/python3 scripts/charts/diligent.py "$csv" "$out"
