"""Draws docs/charts/color_speed_accuracy.png from color_models.csv (written by
scripts/chart-color.sh). Usage: color.py CHART_DIR"""

import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MARKERS = {"linear": "o", "affine": "s", "root-poly-2": "^", "root-poly-3": "v", "poly-2": "D",
           "poly-3": "P", "opencv-3x3": "X"}
COLOURS = {"nikon-5100": "tab:blue", "sigma-sdmerill": "tab:orange", "canon-5d-mark-ii": "tab:green"}


def main():
    chart_dir = Path(sys.argv[1])
    with open(chart_dir / "color_models.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), sharey=True)
    for ax, loss in zip(axes, ["xyz", "ciede2000"]):
        for row in rows:
            is_opencv = row["model"] == "opencv-3x3"
            if row["loss"] != loss and not is_opencv:
                continue
            x, y = float(row["fit_loo_ms"]), float(row["held_out_mean"])
            ax.scatter(x, y, marker=MARKERS.get(row["model"], "o"), color=COLOURS.get(row["camera"], "k"),
                       s=110 if row["chosen"] == "1" else 55, edgecolors="k" if row["chosen"] == "1" else "none")
            ax.annotate(row["model"], (x, y), fontsize=7, xytext=(4, 3), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_xlabel("fit + leave-one-out time (ms, log)")
        ax.set_title(f"our models fitted with {loss} loss (OpenCV 3x3: CIEDE2000 loss)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("held-out (leave-one-out) mean CIEDE2000")
    handles = [plt.Line2D([], [], color=c, marker="o", linestyle="", label=cam) for cam, c in COLOURS.items()]
    handles.append(plt.Line2D([], [], color="w", marker="o", markeredgecolor="k", markersize=10, linestyle="",
                              label="chosen (black edge)"))
    axes[1].legend(handles=handles, loc="upper right", fontsize=8)
    fig.suptitle("Colour models on simulated ColorChecker captures (D65, 400-680 nm): accuracy vs time")
    fig.tight_layout()
    fig.savefig(chart_dir / "color_speed_accuracy.png", dpi=110)


if __name__ == "__main__":
    main()
