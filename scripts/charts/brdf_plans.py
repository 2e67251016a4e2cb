"""Draws docs/charts/brdf_plan_error.png and docs/charts/brdf_plan_models.png
from docs/charts/brdf_plans.csv and brdf_plan_models.csv (written by
photorig-brdf-plan-chart). Usage: brdf_plans.py CHART_DIR"""

import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def main(chart_dir):
    chart_dir = Path(chart_dir)
    plans = read(chart_dir / "brdf_plans.csv")
    materials = list(dict.fromkeys(r["material"] for r in plans))
    fig, axes = plt.subplots(2, len(materials), figsize=(5 * len(materials), 8), sharey=True)
    for col, material in enumerate(materials):
        for plan, style in (("uniform", "o-"), ("adaptive", "s--")):
            rows = [r for r in plans if r["material"] == material and r["plan"] == plan]
            err = [100 * float(r["relative_error"]) for r in rows]
            axes[0][col].plot([int(r["poses"]) for r in rows], err, style, label=plan)
            axes[1][col].plot([float(r["measurement_s"]) for r in rows], err, style, label=plan)
        axes[0][col].set_title(material)
        axes[0][col].set_xlabel("poses")
        axes[1][col].set_xlabel("measurement time (s): arm moves + exposures")
        for ax in (axes[0][col], axes[1][col]):
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
    for row in axes:
        row[0].set_ylabel("relative RMS error of f cos(theta_i) (%)")
    fig.suptitle("Pose plans on the simulated gonioreflectometer, true model fitted, 2 % + 0.002/sr noise, median of 5")
    fig.tight_layout()
    fig.savefig(chart_dir / "brdf_plan_error.png", dpi=110)

    models = read(chart_dir / "brdf_plan_models.csv")
    names = list(dict.fromkeys(r["model"] for r in models))
    fig, ax = plt.subplots(figsize=(10, 4.5))
    width = 0.8 / len(names)
    for i, name in enumerate(names):
        rows = {r["material"]: r for r in models if r["model"] == name}
        x = [m + (i - (len(names) - 1) / 2) * width for m in range(len(materials))]
        ax.bar(x, [float(rows[m]["held_out_rms_sigma"]) for m in materials], width, label=name)
    ax.axhline(1.0, color="k", lw=0.8, ls=":")
    ax.set_xticks(range(len(materials)))
    poses = models[0]["poses"]
    ax.set_xticklabels(materials)
    ax.set_yscale("log")
    ax.set_ylim(0.5, 100)
    ax.set_ylabel("5-fold held-out RMS residual (sigmas)")
    ax.set_title(f"Each model's held-out error, uniform plan of {poses} poses, 2 % + 0.002/sr noise, median of 5")
    ax.legend(loc="upper center", ncol=len(names))
    ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(chart_dir / "brdf_plan_models.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1])
