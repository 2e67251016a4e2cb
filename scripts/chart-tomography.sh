#!/usr/bin/env bash
# Tomography: ART, SIRT, CGLS and SART (with and without total variation) on
# the 128 x 128 Shepp-Logan slice from 64
# views (noise-free and 1 % noise), error against processor time and against
# the number of views, beside scikit-image's SART and filtered back-projection
# on the same sinograms -> docs/charts/tomography_*.png and tomo_*.csv. Both
# sides run on one thread; the whole-process runs are timed with /usr/bin/time.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
out=docs/charts
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
"$build_dir/bin/photorig-tomo-chart" "$out" 128 64
/usr/bin/python3 scripts/charts/tomography.py peer "$out"
/usr/bin/python3 scripts/charts/tomography.py plot "$out" "$out"
# Whole processes: read the noisy sinogram, reconstruct, write the result.
processes="$out/tomo_processes.csv"
echo "process,user_s,system_s,wall_s" > "$processes"
for method in sirt art sart sart-tv; do
  /usr/bin/time -a -o "$processes" -f "photorig $method (stopped),%U,%S,%e" \
    "$build_dir/bin/photorig-tomo-chart" "$out" 128 64 --solve "$method" 2>/dev/null
done
/usr/bin/time -a -o "$processes" -f "scikit-image SART (20 passes),%U,%S,%e" \
  /usr/bin/python3 scripts/charts/tomography.py solve "$out" 2>/dev/null
rm -f "$out"/tomo_slice_*.f32 "$out"/tomo_slice_*.nrrd
cat "$processes"
