"""Normal integration: RMS depth error against time per method and image size."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

rows = list(csv.DictReader(open(sys.argv[1])))
out = sys.argv[2]
fig, ax = plt.subplots(figsize=(7, 5))
for method, marker in (("poisson", "o"), ("poisson, workspace kept", "s"), ("frankot-chellappa", "^")):
    pts = sorted((int(r["unknowns"]), r) for r in rows if r["method"] == method)
    if not pts:
        continue
    times = [float(r["time_ms"]) for _, r in pts]
    errors = [float(r["rms_error_px"]) for _, r in pts]
    ax.plot(times, errors, marker=marker, label=method)
    for (_, r), t, e in zip(pts, times, errors):
        ax.annotate(f'{r["side_px"]} px', (t, e), fontsize=7, textcoords="offset points", xytext=(4, 4))
ax.set_xscale("log")
ax.set_yscale("log")
ax.set_xlabel("time (ms, log; two threads)")
ax.set_ylabel("RMS depth error against the sphere (px, log)")
ax.set_title("Normal integration on a sphere's disc")
ax.legend()
fig.tight_layout()
fig.savefig(f"{out}/integration_error_vs_time.png", dpi=110)
