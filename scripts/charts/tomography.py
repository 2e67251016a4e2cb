"""Tomography: scikit-image's reconstructions of the same slice problem, and the charts.

  tomography.py peer DIR     SART (non-negative, passes 1..20) and filtered back-projection on
                             DIR/tomo_slice_sinogram_{clean,noisy}.f32 -> DIR/tomo_peer.csv
  tomography.py solve DIR    20 SART passes on the noisy sinogram: the whole-process run timed
                             against photorig-tomo-chart --solve
  tomography.py plot DIR OUT charts from DIR/tomo_{iterations,views,peer}.csv -> OUT/tomography_*.png

Conventions: photorig's sinogram (views x columns, column u running along (-sin t, cos t)) is
scikit-image's transposed, with the detector flipped and the angles t - 90 degrees; its pixel
grid has its centre pixel (n/2, n/2) on the axis, so its ground truth is the phantom rasterised
on that grid (tomo_slice_peer_truth.f32). The error is the relative L2 inside the circle.
Times are processor time (time.process_time), as photorig-tomo-chart records its own.
"""
import csv
import sys
import time

import numpy as np


def problem(d):
    meta = dict(line.split() for line in open(f"{d}/tomo_slice.txt"))
    n, views = int(meta["n"]), int(meta["views"])
    pixel = float(meta["pixel_mm"])
    truth = np.fromfile(f"{d}/tomo_slice_peer_truth.f32", np.float32).reshape(n, n)
    theta = np.arange(views) * float(meta["span_deg"]) / views - 90.0
    yy, xx = np.mgrid[:n, :n]
    inside = ((xx - n // 2) ** 2 + (yy - n // 2) ** 2) < (n / 2) ** 2

    def sinogram(which):
        s = np.fromfile(f"{d}/tomo_slice_sinogram_{which}.f32", np.float32).reshape(views, n)
        # b is in sigma * mm; scikit-image's image units are per pixel.
        return (s[:, ::-1].T / pixel).astype(np.float64)

    def error(img):
        return float(np.sqrt(((img - truth)[inside] ** 2).sum() / (truth[inside] ** 2).sum()))

    return sinogram, error, theta


def peer(d):
    from skimage.transform import iradon, iradon_sart

    sinogram, error, theta = problem(d)
    with open(f"{d}/tomo_peer.csv", "w") as out:
        out.write("method,noise,iteration,elapsed_ms,error\n")
        for noisy, which in ((0, "clean"), (1, "noisy")):
            s = sinogram(which)
            t0 = time.process_time()
            fbp = iradon(s, theta=theta, filter_name="ramp", circle=True)
            out.write(f"fbp,{noisy},1,{(time.process_time() - t0) * 1e3:.3f},{error(fbp):.5f}\n")
            image, elapsed = None, 0.0
            for p in range(1, 21):
                t0 = time.process_time()
                image = iradon_sart(s, theta=theta, image=image, clip=(0.0, np.inf))
                elapsed += time.process_time() - t0
                out.write(f"sart,{noisy},{p},{elapsed * 1e3:.3f},{error(image):.5f}\n")


def solve(d):
    from skimage.transform import iradon_sart

    sinogram, error, theta = problem(d)
    s = sinogram("noisy")
    image = None
    for _ in range(20):
        image = iradon_sart(s, theta=theta, image=image, clip=(0.0, np.inf))
    print(f"sart 20 passes: error {error(image):.4f}", file=sys.stderr)


def plot(d, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ours = list(csv.DictReader(open(f"{d}/tomo_iterations.csv")))
    peer_rows = list(csv.DictReader(open(f"{d}/tomo_peer.csv")))
    colours = {"art": "C0", "sirt": "C1", "cgls": "C2", "sart": "C5", "sart-tv": "C6", "peer-sart": "C3", "fbp": "C4"}
    ours_methods = ("art", "sirt", "cgls", "sart", "sart-tv")
    label = {"art": "ART", "sirt": "SIRT", "cgls": "CGLS", "sart": "SART", "sart-tv": "SART + TV"}
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), sharey=True)
    for noisy, ax in zip((0, 1), axes):
        for m in ours_methods:
            rows = [r for r in ours if r["method"] == m and int(r["noise"]) == noisy]
            ax.plot([float(r["elapsed_ms"]) for r in rows], [float(r["error"]) for r in rows], color=colours[m],
                    label=f"photorig {label[m]}")
            for r in rows:
                if r["stopped"] == "1":
                    ax.scatter(float(r["elapsed_ms"]), float(r["error"]), color=colours[m], marker="*", s=160,
                               zorder=5, label=f"{label[m]} stopped (discrepancy)")
        rows = [r for r in peer_rows if r["method"] == "sart" and int(r["noise"]) == noisy]
        ax.plot([float(r["elapsed_ms"]) for r in rows], [float(r["error"]) for r in rows], "o-", color=colours["peer-sart"],
                ms=3, label="scikit-image SART (passes 1-20)")
        for r in peer_rows:
            if r["method"] == "fbp" and int(r["noise"]) == noisy:
                ax.scatter(float(r["elapsed_ms"]), float(r["error"]), color=colours["fbp"], marker="s", s=60,
                           label="scikit-image FBP")
        ax.set_xscale("log")
        ax.set_xlabel("processor time, one thread (ms, log)")
        ax.set_title(("1 % Gaussian noise" if noisy else "noise-free") + ", 128 x 128, 64 views")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("relative L2 error inside the circle")
    axes[0].set_ylim(0.0, 0.45)
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/tomography_error_vs_time.png", dpi=110)

    views = list(csv.DictReader(open(f"{d}/tomo_views.csv")))
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for m in ours_methods:
        for noisy, style in ((0, "--"), (1, "-")):
            rows = [r for r in views if r["method"] == m and int(r["noise"]) == noisy]
            ax.plot([int(r["views"]) for r in rows], [float(r["error"]) for r in rows], style, marker="o",
                    color=colours[m], label=f"{label[m]} {'1 % noise' if noisy else 'noise-free'}")
    ax.set_xlabel("views over 180 degrees")
    ax.set_ylabel("relative L2 error (automatic stop)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/tomography_error_vs_views.png", dpi=110)


if __name__ == "__main__":
    {"peer": lambda: peer(sys.argv[2]), "solve": lambda: solve(sys.argv[2]),
     "plot": lambda: plot(sys.argv[2], sys.argv[3])}[sys.argv[1]]()
