"""Draws docs/charts/brdf_fit_error_vs_time.png from docs/charts/brdf_fits.csv
(written by photorig-brdf-chart). Usage: brdf.py CHART_DIR"""

import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(chart_dir):
    chart_dir = Path(chart_dir)
    with open(chart_dir / "brdf_fits.csv", newline="") as f:
        data = list(csv.DictReader(f))
    materials = list(dict.fromkeys(r["material"] for r in data))
    fig, axes = plt.subplots(1, len(materials), figsize=(5 * len(materials), 4.2), sharey=True)
    for ax, material in zip(axes, materials):
        lines = defaultdict(list)
        for r in data:
            if r["material"] == material and r["fit_ms"] != "nan":
                lines[r["model"]].append(r)
        for model, rows in lines.items():
            x = [float(r["fit_ms"]) for r in rows]
            y = [float(r["relative_error"]) for r in rows]
            ax.plot(x, y, "o-", label=model)
            for r, xi, yi in zip(rows, x, y):
                if r["samples"] in ("20", "320", "2560"):
                    ax.annotate(r["samples"], (xi, yi), textcoords="offset points", xytext=(3, 3), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"truth: {material}")
        ax.set_xlabel("fit time per model (ms), labels: samples")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    axes[0].set_ylabel("relative RMS error of f cos(theta_i), held out")
    fig.suptitle("BRDF fits on synthetic measurements (2 % + 0.002/sr noise), median of 5")
    fig.tight_layout()
    fig.savefig(chart_dir / "brdf_fit_error_vs_time.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1])
