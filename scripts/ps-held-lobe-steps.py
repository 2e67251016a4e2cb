#!/usr/bin/python3
"""How many Gauss-Newton steps a pixel of bench_ps's shiny sphere needs with
its region's lobe held: the check behind the region-first design for shiny
`auto` (docs/performance.md, "Shiny `auto`").

The sphere's pixels as bench_ps renders them (48 lights at 20-80 deg
elevation, rho_d 0.6, Blinn-Phong rho_s 0.3 and e 50, read noise 2 DN, shot
gain 0.05, scale 3000); each pixel's normal and rho_d are stepped by
Gauss-Newton with rho_s and e held at the truth, from three starts: the
Lambertian least squares on the usable samples (the Lambertian pass's
answer), the trimmed Lambertian fit (auto's step 3: the worst sample dropped
until chi-square passes its 0.999 quantile, at most a quarter of them), and
the true normal tilted by 1, 2 and 4 deg (a neighbour's solved normal). The
pass weighs every usable sample alike; trimming weighs each by its noise.
Prints the mean and 99th percentile of the angular error after each number
of steps. Usage: scripts/ps-held-lobe-steps.py [pixels]  (default 2000)
"""
import sys

import numpy as np
from scipy.stats import chi2

LIGHTS = 48
SCALE, READ_SIGMA, SHOT_GAIN, SHADOW = 3000.0, 2.0, 0.05, 6.0
RHO_D, RHO_S, EXPONENT = 0.6, 0.3, 50.0

elevation = np.deg2rad(20 + 60 * (np.arange(LIGHTS) % 4) / 3.0)
azimuth = 2 * np.pi * np.arange(LIGHTS) / LIGHTS
W = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], 1)
H = W + np.array([0.0, 0.0, 1.0])
H /= np.linalg.norm(H, axis=1)[:, None]


def radiance(n, rho_d):
    """Blinn-Phong per unit light scale, with the lobe held."""
    c = np.maximum(W @ n, 0.0)
    h = np.maximum(H @ n, 0.0)
    return (rho_d / np.pi + RHO_S * (EXPONENT + 2) / (2 * np.pi) * h ** EXPONENT) * c


def tangents(n):
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def held_lobe_steps(n, rho_d, b, inverse_sigma, steps):
    """Gauss-Newton on (two tangent steps of n, rho_d), Jacobian by forward differences."""
    for _ in range(steps):
        t1, t2 = tangents(n)
        f = radiance(n, rho_d)
        jacobian = np.zeros((LIGHTS, 3))
        for i, t in enumerate((t1, t2)):
            m = n + 1e-6 * t
            jacobian[:, i] = (radiance(m / np.linalg.norm(m), rho_d) - f) / 1e-6
        jacobian[:, 2] = (radiance(n, rho_d + 1e-6) - f) / 1e-6
        step = np.linalg.lstsq(jacobian * inverse_sigma[:, None], (b - f) * inverse_sigma, rcond=None)[0]
        n = n + step[0] * t1 + step[1] * t2
        n /= np.linalg.norm(n)
        rho_d += step[2]
    return n


def lambertian(b, inverse_sigma, keep):
    x = np.linalg.lstsq(W[keep] * inverse_sigma[keep, None], b[keep] * inverse_sigma[keep], rcond=None)[0]
    return x / np.linalg.norm(x), np.pi * np.linalg.norm(x), (W @ x - b) * inverse_sigma


def trimmed(b, inverse_sigma, usable):
    keep = usable.copy()
    while True:
        n, rho_d, r = lambertian(b, inverse_sigma, keep)
        if np.sum(r[keep] ** 2) <= chi2.ppf(0.999, keep.sum() - 3) or keep.sum() <= usable.sum() - usable.sum() // 4:
            return n, rho_d
        keep[np.argmax(np.where(keep, r * r, -1.0))] = False


def degrees(a, b):
    return np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0)))


def main():
    pixels = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    rng = np.random.default_rng(3)
    starts = ["lambertian", "trimmed", "1 deg off", "2 deg off", "4 deg off"]
    step_counts = [0, 1, 2, 3]
    errors = {(s, k): [] for s in starts for k in step_counts}
    for _ in range(pixels):
        theta, phi = np.deg2rad(60) * np.sqrt(rng.random()), 2 * np.pi * rng.random()
        truth = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
        signal = SCALE * radiance(truth, RHO_D)
        sigma = np.sqrt(READ_SIGMA ** 2 + SHOT_GAIN * signal)
        observed = signal + sigma * rng.standard_normal(LIGHTS)
        usable = observed > SHADOW
        b = np.where(usable, observed / SCALE, 0.0)
        inverse_sigma = np.where(usable, SCALE / sigma, 0.0)
        t1, t2 = tangents(truth)
        angle = 2 * np.pi * rng.random()
        for start in starts:
            if start == "lambertian":
                n0, rho_d0, _ = lambertian(b, usable.astype(float), usable)
            elif start == "trimmed":
                n0, rho_d0 = trimmed(b, inverse_sigma, usable)
            else:
                tilt = np.tan(np.deg2rad(float(start.split()[0])))
                n0 = truth + tilt * (np.cos(angle) * t1 + np.sin(angle) * t2)
                n0, rho_d0 = n0 / np.linalg.norm(n0), RHO_D
            for k in step_counts:
                errors[(start, k)].append(degrees(held_lobe_steps(n0.copy(), rho_d0, b, inverse_sigma, k), truth))
    print("start        " + "".join(f"  {k} steps: mean / p99 deg" for k in step_counts))
    for start in starts:
        cells = "".join(f"  {np.mean(errors[(start, k)]):8.3f} / {np.percentile(errors[(start, k)], 99):6.3f}    "
                        for k in step_counts)
        print(f"{start:12s} {cells}")


if __name__ == "__main__":
    main()
