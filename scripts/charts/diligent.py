"""DiLiGenT objects: mean angular error against whole-process time per method, and the table with the means."""
import csv
import math
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

rows = list(csv.DictReader(open(sys.argv[1])))
out = sys.argv[2]
objects = list(dict.fromkeys(r["object"] for r in rows))
methods = list(dict.fromkeys(r["method"] for r in rows))
by = {(r["object"], r["method"]): r for r in rows}

# The table: mean error per object and method, its mean over the objects, unresolved and filled pixels, time.
print("| method | " + " | ".join(objects) + " | mean | unresolved px | filled px | wall s |")
print("|---" * (len(objects) + 5) + "|")
summary = defaultdict(dict)
for m in methods:
    errors = [float(by[(o, m)]["mean_deg"]) for o in objects if (o, m) in by]
    mean = sum(errors) / len(errors) if errors else math.nan
    unresolved = sum(int(float(by[(o, m)]["unresolved"])) for o in objects if (o, m) in by)
    filled = sum(int(float(by[(o, m)]["filled"])) for o in objects if (o, m) in by)
    wall = sum(float(by[(o, m)]["wall_s"]) for o in objects if (o, m) in by)
    summary[m] = {"mean": mean, "wall": wall}
    cells = [f'{float(by[(o, m)]["mean_deg"]):.2f}' if (o, m) in by else "-" for o in objects]
    print(f"| {m} | " + " | ".join(cells) + f" | {mean:.2f} | {unresolved} | {filled} | {wall:.1f} |")

fig, ax = plt.subplots(figsize=(7, 4.5))
for i, o in enumerate(objects):
    pts = [(float(by[(o, m)]["wall_s"]), float(by[(o, m)]["mean_deg"]), m) for m in methods if (o, m) in by]
    ax.plot([p[0] for p in pts], [p[1] for p in pts], linestyle=":", color=f"C{i}", alpha=0.5)
    for t, e, m in pts:
        ax.scatter(t, e, color=f"C{i}", marker="o", s=18)
    ax.annotate(o, (pts[-1][0], pts[-1][1]), fontsize=7, color=f"C{i}")
for m in methods:
    ax.scatter(summary[m]["wall"] / len(objects), summary[m]["mean"], marker="s", s=50, color="black")
    ax.annotate(f"{m} (mean)", (summary[m]["wall"] / len(objects), summary[m]["mean"]), fontsize=7,
                xytext=(4, 4), textcoords="offset points")
ax.set_xscale("log")
ax.set_xlabel("whole-process time per object (s, log)")
ax.set_ylabel("mean angular error vs ground truth (deg)")
ax.set_title("Photometric stereo on DiLiGenT objects: error against time")
fig.tight_layout()
fig.savefig(f"{out}/diligent_error_vs_time.png", dpi=110)
