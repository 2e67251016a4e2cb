# The held-out-angle residual beside scikit-image's on one scan: a 128^2
# Shepp-Logan slice, 128 parallel views over 0..180 degrees (no end view),
# the axis OFFSET_PX (default -5.5) off scikit-image's centre pixel, Poisson
# counts of 12000 in the open beam, written as 16-bit TIFFs with 4 flats and
# 4 darks for `photorig solve tomography --projections OUT`. scikit-image's
# residual (iradon_sart on the even views, 2 passes; radon into the odd ones;
# the same absorbance) is printed for centres shifted by -8..+8 px and kept
# in OUT/skimage.json. docs/tomography.md#held-out-angle-residual-heldoutresidual
#
#   /usr/bin/python3 bench/tomography/held_out_peer.py OUT [OFFSET_PX]
#   build/bin/photorig solve tomography --projections OUT
import json, os, sys, numpy as np, tifffile
from skimage.data import shepp_logan_phantom
from skimage.transform import radon, iradon_sart, resize
from scipy.ndimage import shift as nd_shift

out = sys.argv[1]
offset_px = float(sys.argv[2]) if len(sys.argv) > 2 else -5.5
n, views = 128, 128
rng = np.random.default_rng(1)
img = resize(shepp_logan_phantom(), (n, n), anti_aliasing=True)
theta = np.arange(views) * 180.0 / views
sino = radon(img, theta=theta, circle=True)           # (n detector, views)
sino = nd_shift(sino, (offset_px, 0), order=3, mode='constant')  # the axis off the detector centre
b = sino * (2.0 / sino.max())
I0, dark = 12000.0, 200.0
def frame(tr):  # counts with shot and read noise
    return np.clip(np.round(rng.poisson(I0 * tr) + dark + rng.normal(0, 3, tr.shape)), 0, 65535).astype(np.uint16)
for d in ("projections", "flats", "darks"): os.makedirs(os.path.join(out, d), exist_ok=True)
for v in range(views): tifffile.imwrite(os.path.join(out, "projections", "%04d.tif" % v), frame(np.exp(-b[:, v]))[None, :])
for k in range(4):
    tifffile.imwrite(os.path.join(out, "flats", "%04d.tif" % k), frame(np.ones(n))[None, :])
    tifffile.imwrite(os.path.join(out, "darks", "%04d.tif" % k), frame(np.zeros(n))[None, :])
json.dump({"beam": "parallel", "detector_cols": n, "detector_rows": 1, "pixel_mm": 1.0, "angles_deg": theta.tolist(),
           "cor_offset_mm": 0.0, "saturation_dn": 65535}, open(os.path.join(out, "geometry.json"), "w"))
# scikit-image's held-out residual over shifted centres, on the same frames' absorbance.
P = np.stack([tifffile.imread(os.path.join(out, "projections", "%04d.tif" % v))[0].astype(float) for v in range(views)], 1)
F = np.mean([tifffile.imread(os.path.join(out, "flats", "%04d.tif" % k))[0].astype(float) for k in range(4)], 0)
D = np.mean([tifffile.imread(os.path.join(out, "darks", "%04d.tif" % k))[0].astype(float) for k in range(4)], 0)
bm = -np.log(np.clip((P - D[:, None]) / (F - D)[:, None], 1e-6, None))
even, odd = np.arange(0, views, 2), np.arange(1, views, 2)
def held_out(c, passes=2):
    s = nd_shift(bm, (-c, 0), order=1, mode='nearest')
    rec = None
    for _ in range(passes): rec = iradon_sart(s[:, even], theta=theta[even], image=rec, clip=(0, None))
    pred = radon(rec, theta=theta[odd], circle=True)
    return np.linalg.norm(pred - s[:, odd]) / np.linalg.norm(s[:, odd])
res = {}
for c in [0.0] + list(np.arange(-8, 8.01, 0.5)):
    res[float(c)] = held_out(c)
best = min(res, key=res.get)
print("scikit-image held-out residual: nominal %.4f, best %.4f at a shift of %+.1f px (true %+.1f)" % (res[0.0], res[best], best, offset_px))
json.dump({"nominal": res[0.0], "best": res[best], "best_shift_px": best, "curve": res}, open(os.path.join(out, "skimage.json"), "w"))
