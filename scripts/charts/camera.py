"""Draws docs/charts/camera_error_vs_time.png from camera_calibration.csv (photorig-camera-chart):
per lens, each distortion model's error on the sample plane against the calibration's time, and the
error against the number of photographs. Usage: camera.py CHART_DIR"""

import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MODELS = ["none", "k1", "k1-k2", "k1-k2-p1-p2", "k1-k2-p1-p2-k3", "auto"]
STYLE = {"none": "v:", "k1": "o:", "k1-k2": "s:", "k1-k2-p1-p2": "D:", "k1-k2-p1-p2-k3": "x:", "auto": "*-"}


def main(chart_dir):
    chart_dir = Path(chart_dir)
    with open(chart_dir / "camera_calibration.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["noise"] == "0.005"]
    lenses = list(dict.fromkeys(r["lens"] for r in rows))
    fig, axes = plt.subplots(2, len(lenses), figsize=(4.6 * len(lenses), 8), squeeze=False)
    for column, lens in enumerate(lenses):
        series = defaultdict(list)
        for r in rows:
            if r["lens"] == lens:
                series[r["model"]].append((int(r["images"]), float(r["time_ms"]), float(r["plane_rms_px"]), r["chosen"],
                                           r["trusted"] == "1"))
        top, bottom = axes[0][column], axes[1][column]
        for model in MODELS:
            points = sorted(series.get(model, []))
            if not points:
                continue
            width = 2.2 if model == "auto" else 1.0
            line, = top.plot([p[1] for p in points], [p[2] for p in points], STYLE[model], lw=width, label=model)
            bottom.plot([p[0] for p in points], [p[2] for p in points], STYLE[model], lw=width, label=model)
            # A calibration that refused its result (the corners do not reach the image's): hollow.
            refused = [p for p in points if not p[4]]
            for ax, x in ((top, 1), (bottom, 0)):
                ax.plot([p[x] for p in refused], [p[2] for p in refused], STYLE[model][0], ms=10, mfc="none",
                        mec=line.get_color(), ls="none")
            if model == "auto":
                for images, time_ms, error, chosen, _ in points:
                    top.annotate(chosen, (time_ms, error), fontsize=7, xytext=(4, 4), textcoords="offset points")
        for ax in (top, bottom):
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            ax.set_ylabel("RMS miss on the sample plane (px)")
        top.set_xscale("log")
        top.set_xlabel("calibration time (ms, 5 / 9 / 13 photographs)")
        top.set_title(lens)
        bottom.set_xlabel("photographs of the board")
    axes[0][0].legend(fontsize=8)
    fig.suptitle("Checkerboard lens calibration, 384 x 384 px, noise 0.5 % of full scale "
                 "(ringed: refused, the corners do not reach the image's)")
    fig.tight_layout()
    fig.savefig(chart_dir / "camera_error_vs_time.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1])
