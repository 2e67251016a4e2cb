"""Measured materials (photorig-ps-chart --materials): each material's error under `auto` against its best
single method, the table behind it, and every method's mean error against its mean solve time."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

rows = list(csv.DictReader(open(sys.argv[1])))
out = sys.argv[2]
singles = ["l2", "lambertian", "robust", "blinn-phong", "low-frequency"]
methods = singles + ["auto"]
by = {(r["scene"], r["method"]): r for r in rows}
materials = [m for m in dict.fromkeys(r["scene"] for r in rows) if all((m, k) in by for k in methods)]
if not materials:
    sys.exit("ps_materials: no material with every method solved in " + sys.argv[1])


def error(material, method):
    return float(by[(material, method)]["mean_deg"])


# Per material: every method's mean error, the best single method, auto's ratio to it and auto's models.
print("| material | " + " | ".join(methods) + " | best single | auto / best | auto: Lambertian, trimmed, Blinn-Phong, GGX, low-frequency % |")
print("|---" * (len(methods) + 4) + "|")
ratios = []
for m in materials:
    best = min(singles, key=lambda k: error(m, k))
    ratio = error(m, "auto") / error(m, best)
    ratios.append((m, ratio, best))
    a = by[(m, "auto")]
    mix = ", ".join(f'{float(a[k]):.0f}' for k in ["lambertian_pct", "trimmed_pct", "blinn_phong_pct", "ggx_pct",
                                                     "low_frequency_pct"])
    print(f"| {m} | " + " | ".join(f"{error(m, k):.2f}" for k in methods) + f" | {best} | {ratio:.2f} | {mix} |")
means = {k: sum(error(m, k) for m in materials) / len(materials) for k in methods}
times = {k: sum(float(by[(m, k)]["solve_ms"]) for m in materials) / len(materials) for k in methods}
print("| mean | " + " | ".join(f"{means[k]:.2f}" for k in methods) + " | | | |")
best_counts = {k: sum(1 for _, _, b in ratios if b == k) for k in singles}
print("| best single method on | " + " | ".join(str(best_counts[k]) for k in singles) + " | | | | |")
print(f"\nauto's solve time {times['auto'] / times['blinn-phong']:.2f}x blinn-phong's (mean {times['auto']:.0f} ms "
      f"against {times['blinn-phong']:.0f} ms)")
over = [r for r in ratios if r[1] > 1.03]
print(f"\n{len(materials)} materials; auto within 1.03x of the best single method on {len(materials) - len(over)}, "
      f"beyond it on {len(over)}: " + ", ".join(f"{m} {r:.2f}x ({b})" for m, r, b in sorted(over, key=lambda x: -x[1])))

fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.8))
best_errors = [min(error(m, k) for k in singles) for m in materials]
auto_errors = [error(m, "auto") for m in materials]
left.scatter(best_errors, auto_errors, s=14, color="C0")
for m, b, a in zip(materials, best_errors, auto_errors):
    if a > 1.1 * b:  # named where auto misses by more than 10 %
        left.annotate(m.removesuffix("_rgb"), (b, a), fontsize=6, xytext=(3, 2), textcoords="offset points")
low, high = min(best_errors + auto_errors) * 0.8, max(best_errors + auto_errors) * 1.2
left.plot([low, high], [low, high], color="black", linewidth=0.8, label="auto = best single method")
left.plot([low, high], [1.03 * low, 1.03 * high], color="grey", linestyle="--", linewidth=0.8, label="1.03x")
left.set_xscale("log")
left.set_yscale("log")
left.set_xlabel("best single method's mean error (deg, log)")
left.set_ylabel("auto's mean error (deg, log)")
left.set_title(f"{len(materials)} measured materials: auto against the best single method", fontsize=9)
left.legend(fontsize=7)
for i, k in enumerate(methods):
    right.scatter(times[k], means[k], s=40, color=f"C{i}")
    right.annotate(k, (times[k], means[k]), fontsize=8, xytext=(4, 3), textcoords="offset points")
right.set_xscale("log")
right.set_xlabel("mean solve time per material (ms, log)")
right.set_ylabel("mean angular error over the materials (deg)")
right.set_title("every method: error against time", fontsize=9)
fig.tight_layout()
fig.savefig(f"{out}/ps_materials.png", dpi=110)
