"""Charts for photometric stereo from docs/charts/ps_results.csv."""
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

rows = list(csv.DictReader(open(sys.argv[1])))
out = sys.argv[2]
methods = ["l2", "lambertian", "robust", "blinn-phong", "auto", "low-frequency"]
markers = {"l2": "o", "lambertian": "s", "robust": "^", "blinn-phong": "D", "auto": "*", "low-frequency": "v"}
scenes = sorted({(r["source"], r["scene"]) for r in rows})
full = {s: max(int(r["lights"]) for r in rows if (r["source"], r["scene"]) == s) for s in scenes}

# 1. Error against time, per method and scene, at the full light set and base noise.
fig, ax = plt.subplots(figsize=(7, 5))
for i, scene in enumerate(scenes):
    for m in methods:
        pts = [r for r in rows if (r["source"], r["scene"]) == scene and r["method"] == m
               and int(r["lights"]) == full[scene] and float(r["relative_noise"]) == 1.0]
        for r in pts:
            ax.scatter(float(r["solve_ms"]), float(r["mean_deg"]), marker=markers[m], color=f"C{i}",
                       s=70, label=f"{scene[1]} / {m}")
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_xlabel("solve time per stack (ms, log)")
ax.set_ylabel("mean angular error (deg, log)")
ax.set_title("Photometric stereo: accuracy against speed")
ax.legend(fontsize=6, ncol=2)
ax.grid(True, which="both", alpha=0.3)
fig.tight_layout()
fig.savefig(f"{out}/ps_speed_accuracy.png", dpi=120)

# 2 and 3. Error against the number of lights and against noise, per scene.
for key, label, name, select in [
        ("lights", "number of lights", "ps_error_vs_lights", lambda r: float(r["relative_noise"]) == 1.0),
        ("relative_noise", "relative noise (x base)", "ps_error_vs_noise",
         lambda r: int(r["lights"]) == full[(r["source"], r["scene"])])]:
    sim_scenes = [s for s in scenes if s[0] == "sim"]
    fig, axes = plt.subplots(1, len(sim_scenes), figsize=(4 * len(sim_scenes), 3.6), squeeze=False)
    for ax, scene in zip(axes[0], sim_scenes):
        for m in methods:
            pts = sorted((float(r[key]), float(r["mean_deg"])) for r in rows
                         if (r["source"], r["scene"]) == scene and r["method"] == m and select(r))
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=markers[m], label=m)
        ax.set_title(scene[1])
        ax.set_xlabel(label)
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("mean angular error (deg, log)")
    axes[0][-1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/{name}.png", dpi=120)

# 4. The realistic shiny-sphere scenes (photorig-ps-chart --realistic), when present.
realistic_csv = f"{out}/ps_realistic.csv"
try:
    realistic = list(csv.DictReader(open(realistic_csv)))
except FileNotFoundError:
    realistic = []
if realistic:
    effects = list(dict.fromkeys(r["scene"] for r in realistic))
    fig, (ax, ax_nan) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    width = 0.8 / len(methods)
    for i, m in enumerate(methods):
        by = {r["scene"]: r for r in realistic if r["method"] == m}
        xs = [e + (i - (len(methods) - 1) / 2) * width for e in range(len(effects))]
        ax.bar(xs, [float(by[e]["mean_deg"]) if e in by else 0 for e in effects], width, label=m,
               hatch="//" if m == "auto" else None, edgecolor="black", linewidth=0.4)
        ax_nan.bar(xs, [100.0 * int(by[e]["unresolved_usable3"]) / int(by[e]["pixels_with_truth"]) if e in by else 0
                        for e in effects], width, label=m)
    ax.set_yscale("log")
    ax.set_ylabel("mean angular error on resolved pixels (deg, log)")
    ax.set_title("Shiny sphere, 96 lights: what a real capture adds")
    ax.legend(fontsize=7, ncol=5)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax_nan.set_ylabel("unresolved with >= 3\nusable lights (% of mask)")
    ax_nan.set_xticks(range(len(effects)))
    ax_nan.set_xticklabels(effects)
    ax_nan.grid(True, axis="y", alpha=0.3)
    ax_nan.set_ylim(bottom=0)  # a share: with none unresolved, the axis still starts at 0
    fig.tight_layout()
    fig.savefig(f"{out}/ps_realistic.png", dpi=120)
print("wrote", out)
