#!/usr/bin/env bash
# Strong scaling of `photorig solve tomography --mpi`: the recipe's scan
# (config/recipes/tomography.yaml: 64^2 x 8 voxels, 64 views) solved by SIRT
# on 1 and 2 MPI processes of one OpenMP thread each, and in one process on
# two threads for comparison. Prints iterations, solve time per iteration and
# wall time of each (docs/tomography.md, "Distributed over MPI").
#   bench/tomography/mpi_scaling.sh [BUILD_DIR]
set -euo pipefail
build=${1:-build}
photorig="$build/bin/photorig"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMPI_MCA_plm=isolated OMPI_MCA_rmaps_base_oversubscribe=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
"$photorig" run config/recipes/tomography.yaml --out "$work/run" --no-solve > /dev/null 2>&1

report() {  # label, json file, wall seconds
  /usr/bin/python3 - "$@" <<'PY'
import json, sys
label, path, wall = sys.argv[1], sys.argv[2], float(sys.argv[3])
r = json.load(open(path))
t = r["timings_ms"]
print(f"{label:28s} {r['iterations']:4d} it  {t['reconstruct_solve'] / r['iterations']:7.2f} ms/it  "
      f"solve {t['reconstruct_solve'] / 1000:6.2f} s  total {t['total'] / 1000:6.2f} s  wall {wall:6.2f} s")
PY
}
run() {  # label, command...
  local label=$1; shift
  local start end
  start=$(date +%s.%N)
  "$@" --json > "$work/out.json" 2> /dev/null
  end=$(date +%s.%N)
  report "$label" "$work/out.json" "$(echo "$end - $start" | bc)"
}
args=(solve tomography --run "$work/run" --method sirt --out "$work/result")
for round in 1 2 3; do
  echo "round $round (load average $(cut -d' ' -f1 /proc/loadavg))"
  OMP_NUM_THREADS=1 run "1 process, 1 thread" "$photorig" "${args[@]}"
  OMP_NUM_THREADS=1 run "mpirun -np 1, 1 thread" mpirun --allow-run-as-root -np 1 "$photorig" "${args[@]}" --mpi
  OMP_NUM_THREADS=1 run "mpirun -np 2, 1 thread each" mpirun --allow-run-as-root --oversubscribe -np 2 "$photorig" "${args[@]}" --mpi
  OMP_NUM_THREADS=2 run "1 process, 2 threads" "$photorig" "${args[@]}"
done
