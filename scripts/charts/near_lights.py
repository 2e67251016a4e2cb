"""Near LEDs: error and solve time against the LEDs' distance, near-light model vs distant model."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

rows = list(csv.DictReader(open(sys.argv[1])))
out = sys.argv[2]
fig, (error_ax, time_ax) = plt.subplots(1, 2, figsize=(11, 4.5))
labels = {"distant": "distant model", "near": "near model", "near-pinhole": "near model, pinhole camera"}
for model, marker in (("distant", "o"), ("near", "s"), ("near-pinhole", "^")):
    pts = sorted((float(r["radius_mm"]), r) for r in rows if r["model"] == model)
    if not pts:
        continue
    radii = [p[0] for p in pts]
    error_ax.plot(radii, [float(r["mean_deg"]) for _, r in pts], marker=marker, label=f"{labels[model]} (measured)")
    time_ax.plot(radii, [float(r["solve_ms"]) for _, r in pts], marker=marker, label=labels[model])
predicted = sorted((float(r["radius_mm"]), float(r["predicted_distant_bias_deg"])) for r in rows
                   if r["model"] == "distant" and r["predicted_distant_bias_deg"])
if predicted:
    error_ax.plot([p[0] for p in predicted], [p[1] for p in predicted], linestyle="--", color="C0",
                  label="distant model (predicted from the geometry)")
error_ax.axhline(0.5, color="grey", linewidth=0.8, linestyle=":")
for ax in (error_ax, time_ax):
    ax.set_xscale("log")
    ax.set_xlabel("LED distance from the sample (mm, log)")
    ax.legend()
error_ax.set_yscale("log")
error_ax.set_ylabel("mean normal error on the 34 mm sphere (deg, log)")
time_ax.set_yscale("log")
time_ax.set_ylabel("solve time (ms, log)")
for (_, r) in sorted((float(r["radius_mm"]), r) for r in rows if r["model"] == "near"):
    time_ax.annotate(f'{r["rounds"]} rounds', (float(r["radius_mm"]), float(r["solve_ms"])), fontsize=7)
fig.suptitle("Photometric stereo under near LEDs (lambertian, sphere recipe)")
fig.tight_layout()
fig.savefig(f"{out}/near_lights.png", dpi=110)
