#!/usr/bin/env bash
# Near LEDs: the sphere recipe on the simulated dome with its LEDs moved to a
# radius R, solved with the near-light model (lambertian) and as if the LEDs
# were distant (--assume-distant), for R from 60 mm to 1 m, and the same dome
# seen through a pinhole camera (30 deg field of view, 300 mm above the
# sample) solved with the near-light model through its lines of sight ->
# docs/charts/near_lights.csv and near_lights.png (error and time against R).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
photorig="$build_dir/bin/photorig"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
csv=docs/charts/near_lights.csv
echo "radius_mm,model,mean_deg,median_deg,rounds,solve_ms,depth_ms,predicted_distant_bias_deg" >"$csv"
for radius in 60 80 100 150 200 400 1000; do
  echo "LEDs at $radius mm" >&2
  /usr/bin/python3 - "$radius" config/rigs/sim-dome.yaml >"$work/rig-$radius.yaml" <<'PY'
import re, sys
radius = float(sys.argv[1])
text = open(sys.argv[2]).read()
def position(m):
    x, y, z = (radius * float(v) for v in m.groups())
    return f"position_mm: [{x:.4f}, {y:.4f}, {z:.4f}]"
print(re.sub(r"direction: \[ *([-0-9.]+), *([-0-9.]+), *([-0-9.]+)\]", position, text), end="")
PY
  /usr/bin/python3 - "$work/rig-$radius.yaml" >"$work/pinhole-rig-$radius.yaml" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
text = text.replace("  projection: orthographic\n",
                    "  projection: pinhole\n  pinhole: {fx_px: 716.55, distance_mm: 300}\n")
print(re.sub(r"  pixel_pitch_mm: [^\n]*\n", "", text), end="")
PY
  run="$work/run-$radius"
  "$photorig" run config/recipes/ps-sphere.yaml --rig "$work/rig-$radius.yaml" --out "$run" >/dev/null
  "$photorig" run config/recipes/ps-sphere.yaml --rig "$work/pinhole-rig-$radius.yaml" --out "$work/pinhole-run-$radius" \
    --no-solve >/dev/null
  for model in near distant near-pinhole; do
    flags=(--method lambertian)
    [ "$model" = distant ] && flags+=(--assume-distant --max-distant-bias 90)
    source_run=$run
    [ "$model" = near-pinhole ] && source_run="$work/pinhole-run-$radius"
    "$photorig" solve ps --run "$source_run" "${flags[@]}" --integrator none --out "$work/$model-$radius" --json >"$work/$model-$radius.json"
    /usr/bin/python3 - "$radius" "$model" "$work/$model-$radius/report.json" >>"$csv" <<'PY'
import json, sys
radius, model, path = sys.argv[1:]
r = json.load(open(path))
lights = r.get("light_model", {})
truth = r["ground_truth"]
print(",".join(str(v) for v in [radius, model, truth["mean_angular_error_deg"], truth["median_angular_error_deg"],
                                lights.get("rounds", 1), r["timings_ms"]["solve"], lights.get("depth_ms", 0.0),
                                lights.get("predicted_distant_bias_deg", "")]))
PY
  done
done
/usr/bin/python3 scripts/charts/near_lights.py "$csv" docs/charts
