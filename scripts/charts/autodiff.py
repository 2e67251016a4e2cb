"""Draws docs/charts/autodiff_timing.png and autodiff_fd_accuracy.png from the CSVs written by
photorig-autodiff-chart. Usage: autodiff.py CHART_DIR"""

import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STYLE = {  # method -> (colour, marker, line style)
    "evaluation": ("0.55", "", "--"),
    "forward Dual<6>": ("tab:blue", "o", "-"),
    "forward Dual<8>": ("tab:blue", "o", "-"),
    "forward DynamicDual": ("tab:cyan", "v", "-"),
    "reverse": ("tab:red", "s", "-"),
    "symbolic": ("tab:green", "D", "-"),
    "forward difference": ("tab:orange", "^", "-"),
    "central difference": ("tab:purple", "x", "-"),
}


def read(path):
    series = defaultdict(lambda: ([], []))
    with open(path, newline="") as f:
        reader = csv.reader(f)
        next(reader)
        for method, x, y in reader:
            series[method][0].append(float(x))
            series[method][1].append(float(y))
    return series


def plot_timing(ax, series, xlabel, title):
    for method, (xs, ys) in series.items():
        colour, marker, line = STYLE[method]
        label = "one evaluation (no derivative)" if method == "evaluation" else method
        ax.loglog(xs, ys, line, color=colour, marker=marker, markersize=4, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("time per call [s]")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)


def main():
    out = Path(sys.argv[1])

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 5))
    plot_timing(left, read(out / "autodiff_timing_inputs.csv"), "number of inputs",
                "Gradient of a scalar loss, 1 output\n"
                "(Blinn-Phong loss, inputs = intensities of N lights)")
    plot_timing(right, read(out / "autodiff_timing_outputs.csv"), "number of outputs",
                "Jacobian of a vector renderer, 6 inputs\n"
                "(Blinn-Phong pixel, one output per light)")
    fig.tight_layout()
    fig.savefig(out / "autodiff_timing.png", dpi=110)

    accuracy = read(out / "autodiff_fd_accuracy.csv")
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for scheme in ("forward difference", "central difference"):
        colour, marker, _ = STYLE[scheme]
        xs, ys = accuracy[scheme]
        ax.loglog(xs, ys, "-", color=colour, marker=marker, markersize=3, label=scheme)
        (x,), (y,) = accuracy[scheme + " default"]
        ax.loglog([x], [y], "*", color=colour, markersize=14, markeredgecolor="black",
                  label=f"{scheme}, default step {x:.1e}")
    for mode, colour in (("forward mode", "tab:blue"), ("reverse mode", "tab:red")):
        (_,), (y,) = accuracy[mode]
        ax.axhline(y, color=colour, linestyle=":", label=f"{mode} AD ({y:.0e})")
    ax.set_xlabel("relative step h / max(1, |x|)")
    ax.set_ylabel("max abs error vs symbolic Jacobian")
    ax.set_title("Finite differences: truncation (right) vs rounding (left)\n"
                 "Blinn-Phong pixel, 16 lights, 20 random pixels with every light >= 0.1 from a kink",
                 fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "autodiff_fd_accuracy.png", dpi=110)


if __name__ == "__main__":
    main()
