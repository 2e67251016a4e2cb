"""Draws docs/charts/lighting_direction_error.png, lighting_envmap_roundtrip.png, lighting_led_positions.png,
lighting_sh_fit.png, lighting_intensity.png and lighting_led_weights.png from the CSVs written by photorig-lighting-chart. Usage: lighting.py CHART_DIR"""

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

    leds = rows(chart_dir / "lighting_led_positions.csv")
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    flagged = defaultdict(list)  # per panel: the configurations whose every LED was flagged uncertain
    for camera, marker in (("orthographic", "o"), ("pinhole", "s")):
        for ax, sweep, key, label in ((axes[0], "radius", "radius_px", "ball radius in the image (px), noise 2 DN"),
                                      (axes[1], "noise", "noise_dn", "read noise (DN, highlight 3000 DN), balls 49 px")):
            sel = [r for r in leds if r["sweep"] == sweep and r["camera"] == camera]
            x = [float(r[key]) for r in sel]
            ax.plot(x, [float(r["mean_error_mm"]) for r in sel], marker + "-", label=f"{camera}: mean error")
            ax.plot(x, [float(r["max_error_mm"]) for r in sel], marker + "--", label=f"{camera}: max error")
            ax.plot(x, [float(r["mean_predicted_mm"]) for r in sel], marker + ":", label=f"{camera}: mean predicted sigma")
            flagged[ax].extend(f"{camera} at {float(r[key]):.3g}: {r['unusable']} of 12 flagged, none placed"
                               for r in sel if int(r["unusable"]) > 0)
            ax.set_xscale("log")
            ax.set_xlabel(label)
        sel = [r for r in leds if r["camera"] == camera]
        axes[2].plot([float(r["ms_per_led"]) for r in sel], [float(r["mean_error_mm"]) for r in sel], marker,
                     label=camera)
    for ax in axes:
        if flagged[ax]:
            ax.text(0.02, 0.02, "\n".join(flagged[ax]), transform=ax.transAxes, fontsize=7, va="bottom")
        ax.set_yscale("log")
        ax.set_ylabel("LED position error (mm)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper right")
    axes[2].set_xlabel("time per LED (ms), every configuration")
    axes[2].legend()
    axes[0].set_title("12 LEDs of a 250 mm dome, three chrome balls")
    fig.tight_layout()
    fig.savefig(chart_dir / "lighting_led_positions.png", dpi=110)

    sh = rows(chart_dir / "lighting_sh_fit.csv")
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    styles = {"held-out": "o-", "bic": "s--", "band 1": "v:", "band 2": "^:", "band 4": "x:"}
    for selection, style in styles.items():
        sel = [r for r in sh if r["selection"] == selection]
        caps = [float(r["cap_deg"]) for r in sel]
        line, = axes[0].plot(caps, [float(r["error_hemisphere"]) for r in sel], style, label=f"{selection}: error")
        axes[0].plot(caps, [float(r["predicted_hemisphere_sigma"]) for r in sel], style[0], mfc="none", ms=10,
                     color=line.get_color(), ls="none")
        axes[1].plot([float(r["time_ms"]) for r in sel], [float(r["error_seen"]) for r in sel], style[0],
                     color=line.get_color(), label=selection)
    axes[0].axhline(0.05, color="0.6", lw=0.8)
    axes[0].set_xlabel("normals seen: within this angle of the view (deg)")
    axes[0].set_ylabel("relative RMS irradiance error, visible hemisphere")
    axes[0].set_title("SH lighting extrapolated beyond the normals seen\n(rings: predicted sigma at the worst normal)")
    axes[0].invert_xaxis()
    axes[1].set_xlabel("fit time (ms), 256 x 256 sphere")
    axes[1].set_ylabel("relative RMS irradiance error, normals seen")
    axes[1].set_title("on the normals seen, against time")
    for ax in axes:
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(chart_dir / "lighting_sh_fit.png", dpi=110)

    intensity = rows(chart_dir / "lighting_intensity.csv")
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    sheen = [r for r in intensity if r["sweep"] == "sheen"]
    dim = [r for r in intensity if r["sweep"] == "dim8"]
    floor = 1e-5  # zeros (no sheen; no model error) are drawn here
    for ax, sel, key, label in ((axes[0], sheen, "sheen", "sheen: lobe share of the albedo (exponent 20; 0 at left)"),
                                (axes[1], dim, "level", "irradiance (peak = level / pi DN)")):
        x = [max(float(r[key]), 0.002) for r in sel]
        for column, style, name in (("mean_error", "o-", "intensity error, mean"),
                                    ("max_error", "s--", "intensity error, max"),
                                    ("mean_normalised_error", "d-", "error relative to the set's mean"),
                                    ("mean_model_error", "^-", "model error (residual beyond noise)"),
                                    ("mean_relative_residual", "v:", "relative RMS residual")):
            ax.plot(x, [max(float(r[column]), floor) for r in sel], style, label=name)
        ax.axhline(0.05, color="0.6", lw=0.8, label="max_model_error 5 %")
        for xi, r in zip(x, sel):
            if int(r["refused"]) > 0:
                ax.annotate(f"{r['refused']}/{r['lights']}\nrefused", (xi, max(float(r["mean_model_error"]), floor)),
                            fontsize=7, xytext=(-8, -24), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(floor / 2, 1.0)
        ax.set_xlabel(label)
        ax.set_ylabel("relative (to the mean sample or the truth)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_title("white sphere, 48 lights, 2 DN noise: a sheen", fontsize=10)
    axes[1].set_title("dim 8-bit frames, 1.5 DN noise: noise is no model error", fontsize=10)
    for sel, marker, label in ((sheen, "o", "sheen sweep"), (dim, "s", "dim 8-bit sweep")):
        axes[2].plot([float(r["ms_per_light"]) for r in sel],
                     [max(float(r["mean_normalised_error"]), floor) for r in sel], marker, label=label)
    axes[2].set_xlabel("time per light (ms), 230 x 230 RGB frame")
    axes[2].set_ylabel("mean error relative to the set's mean")
    axes[2].set_yscale("log")
    axes[2].grid(True, which="both", alpha=0.3)
    axes[2].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(chart_dir / "lighting_intensity.png", dpi=110)

    weights = rows(chart_dir / "lighting_led_weights.csv")
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for led_set, marker, label in (("simplest", "o", "simplest LED set (BIC)"), ("all", "s", "every LED NNLS drives")):
        for ax, sweep, key in ((axes[0], "noise", "relative_noise"), (axes[1], "stride", "pixel_stride")):
            sel = [r for r in weights if r["sweep"] == sweep and r["led_set"] == led_set]
            x = [max(float(r[key]), 3e-4) for r in sel]
            line, = ax.plot(x, [max(float(r["max_weight_error"]), 1e-6) for r in sel], marker + "-",
                            label=f"{label}: max weight error")
            ax.plot(x, [max(float(r["relit_relative_rms"]), 1e-6) for r in sel], marker + ":", color=line.get_color(),
                    label=f"{label}: relit image error")
            for xi, r in zip(x, sel):
                ax.annotate(r["active_leds"], (xi, max(float(r["max_weight_error"]), 1e-6)), fontsize=7,
                            xytext=(2, 4), textcoords="offset points", color=line.get_color())
        sel = [r for r in weights if r["led_set"] == led_set]
        axes[2].plot([float(r["time_ms"]) for r in sel], [max(float(r["relit_relative_rms"]), 1e-6) for r in sel],
                     marker, label=label)
    axes[0].set_xlabel("image noise relative to its mean (0 at left), every pixel")
    axes[1].set_xlabel("pixel stride, noise 1 %")
    axes[0].set_title("3 of 48 LEDs (drives 0.7, 1.3, 0.5); numbers: LEDs driven", fontsize=10)
    axes[2].set_xlabel("fit time (ms), 256 px sphere")
    axes[2].set_ylabel("relit image error relative to its mean")
    for ax in axes[:2]:
        ax.set_xscale("log")
        ax.set_ylabel("error (drive units; relative)")
    for ax in axes:
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    axes[2].set_xscale("log")
    fig.tight_layout()
    fig.savefig(chart_dir / "lighting_led_weights.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1])
