"""Draws docs/charts/lighting_direction_error.png and lighting_envmap_roundtrip.png from the
CSVs written by photorig-lighting-chart. Usage: lighting.py CHART_DIR"""

import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def main(chart_dir):
    chart_dir = Path(chart_dir)
    data = rows(chart_dir / "lighting_direction_error.csv")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, sweep, key, label in ((axes[0], "radius", "radius_px", "sphere radius (px), noise 3 DN"),
                                  (axes[1], "noise", "noise_dn", "noise sigma (DN), radius 100 px")):
        sel = [r for r in data if r["sweep"] == sweep]
        x = [float(r[key]) for r in sel]
        ax.plot(x, [float(r["mean_error_deg"]) for r in sel], "o-", label="mean error")
        ax.plot(x, [float(r["max_error_deg"]) for r in sel], "s--", label="max error")
        ax.plot(x, [float(r["mean_predicted_deg"]) for r in sel], "^:", label="mean predicted 1-sigma")
        ax.axhline(0.5, color="0.6", lw=0.8)
        ax.set_xscale("log" if sweep == "radius" else "symlog")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("light direction error (deg)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    axes[0].set_title("48-LED dome, orthographic mirror sphere")
    fig.tight_layout()
    fig.savefig(chart_dir / "lighting_direction_error.png", dpi=110)

    env = rows(chart_dir / "lighting_envmap_roundtrip.csv")
    series = defaultdict(lambda: ([], []))
    for r in env:
        xs, ys = series[r["blind_cone_deg"]]
        xs.append(float(r["ball_px"]))
        ys.append(float(r["relative_error"]))
    fig, ax = plt.subplots(figsize=(6, 4))
    for cone, (xs, ys) in series.items():
        ax.plot(xs, ys, "o-", label=f"blind cone {cone} deg")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("mirror-ball diameter (px)")
    ax.set_ylabel("relative L1 error, lat-long -> ball -> lat-long")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(chart_dir / "lighting_envmap_roundtrip.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1])
