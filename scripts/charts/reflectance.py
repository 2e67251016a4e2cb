"""Draws docs/charts/reflectance_error_vs_time.png from docs/charts/reflectance.csv
(written by photorig-reflectance-chart). Usage: reflectance.py CHART_DIR"""

import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(chart_dir):
    chart_dir = Path(chart_dir)
    with open(chart_dir / "reflectance.csv", newline="") as f:
        data = list(csv.DictReader(f))
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))
    lines = defaultdict(list)
    for r in data:
        lines[r["method"]].append(r)
    for method, rows in lines.items():
        x = [float(r["fit_ms"]) for r in rows]
        y = [float(r["heldout_rmse"]) for r in rows]
        left.plot(x, y, "o-", label=method)
        for r, xi, yi in zip(rows, x, y):
            left.annotate(r["pixels"], (xi, yi), textcoords="offset points", xytext=(3, 3), fontsize=7)
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("fit time (ms; per-material: the full fit with model choice), labels: pixels")
    left.set_ylabel("held-out relighting RMSE (4 stratified lights)")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=7)
    for method, colour in (("per_material", "C2"), ("per_material_tilted_normals", "C3"),
                           ("per_material_refined_normals", "C4")):
        rows = lines[method]
        if not rows:
            continue
        x = [float(r["fit_ms"]) for r in rows]
        right.plot(x, [100 * float(r["albedo_error"]) for r in rows], "o-", color=colour,
                   label=method + ": albedo, median relative (%)")
        right.plot(x, [100 * float(r["lobe_error"]) for r in rows], "s--", color=colour,
                   label=method + ": lobe parameters, largest (%)")
    right.set_xscale("log")
    right.set_yscale("log")
    right.set_xlabel("per-material fit time (ms)")
    right.set_ylabel("error against truth (%)")
    right.grid(True, which="both", alpha=0.3)
    right.legend(fontsize=6)
    fig.suptitle("Reflectance on the simulated three-material colour sphere (41 lights, 0.002 + 0.5 % noise);\n"
                 "true normals, normals tilted 2 deg, and those refined jointly with the reflectance", fontsize=9)
    fig.tight_layout()
    fig.savefig(chart_dir / "reflectance_error_vs_time.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1])
