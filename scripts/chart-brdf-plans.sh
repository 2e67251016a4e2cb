#!/usr/bin/env bash
# BRDF pose plans: fit error against poses and measurement time, uniform
# against adaptive plans, and every model's held-out error, on simulated
# measurements of three materials -> docs/charts/brdf_plans.csv and
# brdf_plan_models.csv, drawn as docs/charts/brdf_plan_error.png and
# brdf_plan_models.png.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
"$build_dir/bin/photorig-brdf-plan-chart" config/rigs/sim-gonio.yaml docs/charts
/usr/bin/python3 scripts/charts/brdf_plans.py docs/charts
