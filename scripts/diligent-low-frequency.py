#!/usr/bin/python3
"""A low-frequency reflectance against the trimmed Lambertian fit on DiLiGenT objects.

    /usr/bin/python3 scripts/diligent-low-frequency.py DIR [--objects ball,bear] [--pixels 1000] [--seed 1]
                                                         [--leave-out 0,5,10,20] [--synthetic 0.18,0.35] [--lobes]
                                                         [--shared-retro 0,0.5,1,2,4,8]

DIR holds DiLiGenT-layout object folders (<name>PNG/ with the images, filenames.txt,
light_directions.txt, light_intensities.txt, mask.png and Normal_gt.mat); the project ships none.
For a random sample of each object's masked pixels it fits, from the pixel's own samples:

  trimmed     a Lambertian fit that drops its worst sample while any lies beyond 3 robust sigma
  lowfreq     I_k = (n . l_k) (a0 + a1 (n . h_k) + a2 (n . h_k)^2 + a3 cos theta_d,k), every a >= 0
  lowfreq-N   the same without the pixel's brightest N % of lit samples
  lobe        with --lobes: Lambertian plus a normalised Blinn-Phong lobe, rho_d / pi + rho_s (e + 2) / (2 pi)
              (n . h)^e, from the trimmed fit's normal and the best of five start exponents (3 to 300)
  lobe+retro  the same with a diffuse term that grows towards the camera, a3 (n . l) cos theta_d, a3 >= 0
              (a rough surface's retro-reflection to first order), fitted from the same starts
  lobe-bic    lobe+retro where it lowers the misfit, over the lobe fit's residual variance per degree of
              freedom (at least 1 DN^2), by more than ln(samples) + 10 (the information criterion with
              the margin `auto` uses), else lobe

With --shared-retro K,...: instead of the table above, one retro-reflection factor k shared by every
sampled pixel of an object (or, with --synthetic, of each roughness), diffuse rho_d / pi (1 + k cos
theta_d) beside the Blinn-Phong lobe, each pixel's lobe refitted (five start exponents) at each k given:
per k the misfit summed over the pixels (chi^2 in DN^2) and the mean angular error; then the k an
information criterion picks (one parameter for all the pixels; the margin `auto` uses) and, on the same
pixels, the low-frequency fit without the brightest 10 %.

The low-frequency model is an isotropic reflectance that grows towards the mirror direction and
with the half angle, with no lobe width to fit: a broad lobe seen by its tail, light the surface
sends back to itself and a soft shoulder all fit it, while a sharp spike does not, which is why
the brightest samples are left out. With a fixed view (DiLiGenT's camera looks down -z) cos
theta_d = l . h depends on the light alone, so for a given normal the model is linear in a and
the normal is fitted by variable projection (non-negative least squares inside a 2-parameter
least-squares search over the normal's angles, from the trimmed fit).

With --synthetic, no images are read: pixels of known normal (tilt up to 60 deg) are rendered under
the first object's lights, a Lambertian term of albedo 0.5 plus a GGX lobe (Smith-Schlick shadowing,
Schlick Fresnel with F0 0.3) of each roughness given (0: none), 120 DN diffuse at normal incidence, 0.5 DN
noise and 8-bit rounding: a convex surface with no foreign light, where a lobe model is exact.

Prints the mean angular error against the ground truth per object and method, over all sampled
pixels and split by the true normal's tilt from the view, the edge being the half vectors' cone
(the largest angle between a light's half vector and the view): inside it a pixel's highlight
peak falls among the samples, outside only its tail does.
"""
import argparse
import os
import sys

import cv2
import numpy as np
import scipy.io
from scipy.optimize import least_squares, nnls

VIEW = np.array([0.0, 0.0, 1.0])
MIN_SAMPLES = 8


def load_object(folder):
    lights = np.loadtxt(os.path.join(folder, "light_directions.txt"))
    gains = np.loadtxt(os.path.join(folder, "light_intensities.txt"))
    names = open(os.path.join(folder, "filenames.txt")).read().split()
    values, raw = [], []
    for k, name in enumerate(names):
        image = cv2.imread(os.path.join(folder, name), cv2.IMREAD_UNCHANGED)
        if image is None:
            sys.exit(f"{folder}/{name}: not an image OpenCV can read")
        rgb = image[:, :, ::-1].astype(np.float64)
        values.append((rgb / gains[k]).sum(axis=2))  # grey, each channel divided by its light's colour
        raw.append(image.max(axis=2))
    mask = cv2.imread(os.path.join(folder, "mask.png"), cv2.IMREAD_GRAYSCALE) > 0
    truth = scipy.io.loadmat(os.path.join(folder, "Normal_gt.mat"))["Normal_gt"]
    return lights, np.stack(values, -1), np.stack(raw, -1), mask, truth


def half_vectors(lights):
    """Each light's half vector with the view and cos theta_d = l . h."""
    halves = lights + VIEW
    halves /= np.linalg.norm(halves, axis=1, keepdims=True)
    return halves, halves @ VIEW


def object_samples(directory, name, pixels, seed):
    """One object's lights, half vectors and cos theta_d, and a random sample of `pixels` of its masked pixels
    (0: all) with enough usable samples, each as (values, used, trimmed start, true normal)."""
    folder = os.path.join(directory, name + "PNG")
    if not os.path.isdir(folder):
        sys.exit(f"{folder}: no such object folder (expected DIR/<object>PNG/)")
    lights, values, raw, mask, truth = load_object(folder)
    halves, cos_d = half_vectors(lights)
    rows, cols = np.nonzero(mask)
    rng = np.random.default_rng(seed)
    count = len(rows) if pixels <= 0 else min(pixels, len(rows))
    samples = []
    for i in rng.choice(len(rows), count, replace=False):
        r, c = rows[i], cols[i]
        # lit and unsaturated: 8-bit samples under 2 DN are shadow or noise, 255 clipped
        used = (raw[r, c] >= 2) & (raw[r, c] < 255)
        if used.sum() >= MIN_SAMPLES:
            samples.append((values[r, c], used, trimmed_lambertian(values[r, c], lights, used), truth[r, c]))
    return lights, halves, cos_d, samples


def angle_deg(estimate, truth):
    estimate = estimate / np.linalg.norm(estimate)
    return float(np.degrees(np.arccos(np.clip(estimate @ truth, -1.0, 1.0))))


def lambertian(values, lights, used):
    b, *_ = np.linalg.lstsq(lights[used], values[used], rcond=None)
    return b


def trimmed_lambertian(values, lights, used):
    used = used.copy()
    while True:
        b = lambertian(values, lights, used)
        residual = np.where(used, np.abs(values - lights @ b), -1.0)
        sigma = 1.4826 * np.median(residual[used]) + 1e-12
        worst = int(np.argmax(residual))
        if residual[worst] <= 3.0 * sigma or used.sum() <= MIN_SAMPLES:
            return b
        used[worst] = False


def unit(theta, phi):
    return np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def low_frequency(values, lights, halves, cos_d, used, start, drop_fraction):
    if drop_fraction > 0.0:
        used = used & (values <= np.quantile(values[used], 1.0 - drop_fraction))
    l, h, d, y = lights[used], halves[used], cos_d[used], values[used]

    def columns(n):
        nl = np.maximum(l @ n, 0.0)
        nh = np.clip(h @ n, 0.0, 1.0)
        return np.stack([nl, nl * nh, nl * nh * nh, nl * d], axis=1)

    def residuals(angles):
        design = columns(unit(*angles))
        a, _ = nnls(design, y)
        return design @ a - y

    start = start / np.linalg.norm(start)
    angles = [np.arccos(np.clip(start[2], -1.0, 1.0)), np.arctan2(start[1], start[0])]
    fit = least_squares(residuals, angles, method="trf", x_scale=0.1, diff_step=1e-4)
    return unit(*fit.x)


def lobe_fits(values, lights, halves, cos_d, used, start):
    """Normals of lobe, lobe+retro and lobe-bic (see the module's help) from one pixel's samples."""
    l, h, d, y = lights[used], halves[used], cos_d[used], values[used]

    def predict(x):  # the lobe beside a diffuse with its own retro-reflection term a3 = x[5]
        n = unit(x[0], x[1])
        nl = np.maximum(l @ n, 0.0)
        nh = np.clip(h @ n, 0.0, 1.0)
        e = np.exp(x[4])
        return nl * (x[2] / np.pi + x[5] * d + x[3] * (e + 2.0) / (2.0 * np.pi) * nh ** e)

    s = start / np.linalg.norm(start)
    albedo = np.pi * np.linalg.norm(start)
    retro = None
    for exponent in (3.0, 10.0, 30.0, 100.0, 300.0):
        x0 = [np.arccos(np.clip(s[2], -1.0, 1.0)), np.arctan2(s[1], s[0]), albedo, 0.05 * albedo, np.log(exponent),
              1e-9]
        result = least_squares(lambda x: predict(x) - y, x0, x_scale="jac",
                               bounds=([-np.inf, -np.inf, 0.0, 0.0, 0.0, 0.0],
                                       [np.inf, np.inf, np.inf, np.inf, np.log(2000.0), np.inf]))
        if retro is None or result.cost < retro.cost:
            retro = result
    retro_normal, retro_misfit = unit(retro.x[0], retro.x[1]), 2.0 * retro.cost
    lobe, lobe_misfit, _ = lobe_with_retro_factor(values, lights, halves, cos_d, used, start, 0.0)
    variance = max(1.0, lobe_misfit / max(1, len(y) - 5))
    chosen = retro_normal if (lobe_misfit - retro_misfit) / variance > np.log(len(y)) + 10.0 else lobe
    return {"lobe": lobe, "lobe+retro": retro_normal, "lobe-bic": chosen}


def lobe_with_retro_factor(values, lights, halves, cos_d, used, start, factor, previous=None):
    """Normal, misfit (chi^2, DN^2) and parameters of a Blinn-Phong lobe beside the diffuse
    rho_d / pi (1 + factor cos theta_d); previous: (factor, parameters) of the pixel's fit at another
    factor, a sixth start (rho_d rescaled), so that a larger factor never ends above a smaller one's fit."""
    l, h, d, y = lights[used], halves[used], cos_d[used], values[used]

    def predict(x):
        n = unit(x[0], x[1])
        nl = np.maximum(l @ n, 0.0)
        nh = np.clip(h @ n, 0.0, 1.0)
        e = np.exp(x[4])
        return nl * (x[2] / np.pi * (1.0 + factor * d) + x[3] * (e + 2.0) / (2.0 * np.pi) * nh ** e)

    s = start / np.linalg.norm(start)
    albedo = np.pi * np.linalg.norm(start) / (1.0 + factor)
    starts = [[np.arccos(np.clip(s[2], -1.0, 1.0)), np.arctan2(s[1], s[0]), albedo, 0.05 * albedo, np.log(exponent)]
              for exponent in (3.0, 10.0, 30.0, 100.0, 300.0)]
    if previous is not None:
        x = np.array(previous[1], dtype=float)
        x[2] *= (1.0 + previous[0]) / (1.0 + factor)
        starts.append(list(x))
    best = None
    for x0 in starts:
        result = least_squares(lambda x: predict(x) - y, x0, x_scale="jac",
                               bounds=([-np.inf, -np.inf, 0.0, 0.0, 0.0], [np.inf, np.inf, np.inf, np.inf, np.log(2000.0)]))
        if best is None or result.cost < best.cost:
            best = result
    return unit(best.x[0], best.x[1]), 2.0 * best.cost, best.x


def shared_retro(name, lights, halves, cos_d, pixels, factors):
    """Prints the --shared-retro rows for one scene's sampled pixels (as object_samples gives them): per k
    the summed misfit and mean error, then the k the criterion picks and, on the same pixels, the
    low-frequency fit without the brightest 10 %."""
    results = []
    previous = [None] * len(pixels)  # each pixel's fit at the last factor, factors taken in the order given
    for factor in factors:
        misfit, errors = 0.0, []
        for i, (values, used, start, truth) in enumerate(pixels):
            normal, chi2, x = lobe_with_retro_factor(values, lights, halves, cos_d, used, start, factor, previous[i])
            previous[i] = (factor, x)
            misfit += chi2
            errors.append(angle_deg(normal, truth))
        results.append((factor, misfit, float(np.mean(errors))))
        print(f"| {name} | {len(pixels)} | {factor:g} | {misfit:.4g} | {np.mean(errors):.2f} |", flush=True)
    # The factor is one parameter for every pixel: kept where it lowers the misfit, over the lobe fits'
    # residual variance per degree of freedom (at least 1 DN^2), by more than ln(samples) + 10.
    samples = sum(int(used.sum()) for _, used, _, _ in pixels)
    dof = samples - 5 * len(pixels)
    base = next((r for r in results if r[0] == 0.0), None)
    if base is not None:
        variance = max(1.0, base[1] / max(1, dof))
        best = min(results, key=lambda r: r[1])
        picked = best if (base[1] - best[1]) / variance > np.log(samples) + 10.0 else base
        low = [angle_deg(low_frequency(v, lights, halves, cos_d, u, st, 0.1), t) for v, u, st, t in pixels]
        print(f"| {name} | {len(pixels)} | picked {picked[0]:g} (gain {(base[1] - best[1]) / variance:.3g}) | | "
              f"{picked[2]:.2f}; low-frequency-10 {np.mean(low):.2f} |", flush=True)


def estimate(methods, values, lights, halves, cos_d, used, start):
    """Each method's normal for one pixel: None the trimmed fit, a number a low-frequency fit leaving
    out that share of the brightest samples, "lobe" the lobe fits."""
    lobes = None
    normals = {}
    for method, spec in methods.items():
        if spec is None:
            normals[method] = start
        elif spec == "lobe":
            lobes = lobes or lobe_fits(values, lights, halves, cos_d, used, start)
            normals[method] = lobes[method]
        else:
            normals[method] = low_frequency(values, lights, halves, cos_d, used, start, spec)
    return normals


def render_ggx(normal, lights, halves, cos_d, roughness, rng):
    albedo, f0 = 0.5, 0.3
    nl = np.maximum(lights @ normal, 0.0)
    if roughness == 0.0:  # no lobe: a Lambertian surface
        return np.round(np.clip(nl * 120.0 + rng.normal(0.0, 0.5, nl.shape), 0.0, 255.0))
    nv = normal @ VIEW
    nh = np.clip(halves @ normal, 0.0, 1.0)
    a2 = roughness * roughness
    distribution = a2 / (np.pi * (nh * nh * (a2 - 1.0) + 1.0) ** 2)
    k = roughness / 2.0
    shadowing = (nl / (nl * (1.0 - k) + k)) * (nv / (nv * (1.0 - k) + k))
    fresnel = f0 + (1.0 - f0) * (1.0 - cos_d) ** 5
    specular = distribution * shadowing * fresnel / np.maximum(4.0 * nl * nv, 1e-6)
    radiance = (albedo / np.pi + specular) * nl
    dn = radiance * 120.0 / (albedo / np.pi) + rng.normal(0.0, 0.5, radiance.shape)
    return np.round(np.clip(dn, 0.0, 255.0))


def synthetic_samples(lights, halves, cos_d, roughness, draws, rng):
    """`draws` pixels of random normal (tilt up to 60 deg) rendered with render_ggx, those with enough usable
    samples kept as object_samples keeps them: (values, used, trimmed start, true normal)."""
    samples = []
    for _ in range(draws):
        tilt, azimuth = np.radians(rng.uniform(0.0, 60.0)), rng.uniform(0.0, 2.0 * np.pi)
        normal = unit(tilt, azimuth)
        values = render_ggx(normal, lights, halves, cos_d, roughness, rng)
        used = (values >= 2) & (values < 255)
        if used.sum() >= MIN_SAMPLES:
            samples.append((values, used, trimmed_lambertian(values, lights, used), normal))
    return samples


def synthetic(lights, roughnesses, pixels, seed, methods):
    halves, cos_d = half_vectors(lights)
    rng = np.random.default_rng(seed)
    print("| GGX roughness | pixels | " + " | ".join(methods) + " |")
    print("|---|---|" + "---|" * len(methods))
    for roughness in roughnesses:
        errors = {m: [] for m in methods}
        for values, used, start, normal in synthetic_samples(lights, halves, cos_d, roughness, pixels, rng):
            for method, n in estimate(methods, values, lights, halves, cos_d, used, start).items():
                errors[method].append(angle_deg(n, normal))
        means = " | ".join(f"{np.mean(errors[m]):.2f}" for m in methods)
        print(f"| {roughness:g} | {len(errors['trimmed'])} | {means} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dir")
    parser.add_argument("--objects", default="ball,bear,goblet,pot1,reading")
    parser.add_argument("--pixels", type=int, default=1000, help="pixels sampled per object; 0: every masked pixel")
    parser.add_argument("--leave-out", default="0,5,10,20", metavar="PERCENT,...",
                        help="the low-frequency fits to run, by the share of brightest lit samples left out")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--synthetic", metavar="ROUGHNESS,...",
                        help="render GGX pixels of these roughnesses under the first object's lights instead")
    parser.add_argument("--lobes", action="store_true",
                        help="also fit lobe, lobe+retro and lobe-bic (slow: ten lobe fits per pixel)")
    parser.add_argument("--shared-retro", metavar="K,...",
                        help="instead: one retro-reflection factor shared by each object's sampled pixels, at each K")
    args = parser.parse_args()
    if args.shared_retro:
        factors = [float(k) for k in args.shared_retro.split(",")]
        print("| object | pixels | shared k | misfit, DN^2 | mean error, deg |")
        print("|---|---|---|---|---|")
        if args.synthetic:
            first = os.path.join(args.dir, args.objects.split(",")[0] + "PNG", "light_directions.txt")
            lights = np.loadtxt(first)
            halves, cos_d = half_vectors(lights)
            rng = np.random.default_rng(args.seed)
            scenes = [(f"GGX {r:g}", lights, halves, cos_d,
                       synthetic_samples(lights, halves, cos_d, float(r), args.pixels, rng))
                      for r in [float(r) for r in args.synthetic.split(",")]]
        else:
            scenes = [(name, *object_samples(args.dir, name, args.pixels, args.seed))
                      for name in args.objects.split(",")]
        for scene in scenes:
            shared_retro(*scene, factors)
        return
    methods = {"trimmed": None}
    for percent in args.leave_out.split(","):
        methods["lowfreq" if float(percent) == 0 else f"lowfreq-{percent}"] = float(percent) / 100.0
    if args.lobes:
        methods.update({"lobe": "lobe", "lobe+retro": "lobe", "lobe-bic": "lobe"})
    if args.synthetic:
        first = os.path.join(args.dir, args.objects.split(",")[0] + "PNG", "light_directions.txt")
        if not os.path.isfile(first):
            sys.exit(f"{first}: no such file (the lights are read from the first object)")
        roughnesses = [float(r) for r in args.synthetic.split(",")]
        synthetic(np.loadtxt(first), roughnesses, args.pixels, args.seed, methods)
        return
    print("| object | pixels | tilt | " + " | ".join(methods) + " |")
    print("|---|---|---|" + "---|" * len(methods))
    for name in args.objects.split(","):
        lights, halves, cos_d, samples = object_samples(args.dir, name, args.pixels, args.seed)
        cone_deg = float(np.degrees(np.arccos(cos_d.min())))
        errors = {m: [] for m in methods}
        tilts = []
        for pixel, used, start, normal in samples:
            tilts.append(np.degrees(np.arccos(np.clip(normal[2], -1.0, 1.0))))
            for method, n in estimate(methods, pixel, lights, halves, cos_d, used, start).items():
                errors[method].append(angle_deg(n, normal))
        tilts = np.array(tilts)
        bands = [("all", 0.0, 90.0), (f"< {cone_deg:.1f}", 0.0, cone_deg),
                 (f"{cone_deg:.1f}-40", cone_deg, 40.0), ("> 40", 40.0, 90.0)]
        for label, low, high in bands:
            inside = (tilts >= low) & (tilts < high)
            if not inside.any():
                continue
            means = " | ".join(f"{np.mean(np.array(errors[m])[inside]):.2f}" for m in methods)
            print(f"| {name} | {int(inside.sum())} | {label} | {means} |", flush=True)


if __name__ == "__main__":
    main()
