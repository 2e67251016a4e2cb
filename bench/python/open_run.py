#!/usr/bin/python3
"""Opening a run into arrays: photorig.open_run(...).frames() against cv2.imread
of the same PNG files, measured in one process on one run.

Captures a 97-frame (1 dark + 96 LEDs) 1024 x 1024 run on the 96-LED simulated
dome, unless --run names one, then times each reader --repeats times
(alternating, best of each) and prints both and their ratio.

    PYTHONPATH=build/python /usr/bin/python3 bench/python/open_run.py --bin-dir build/bin
"""

import argparse
import subprocess
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

import photorig

SOURCE_DIR = Path(__file__).resolve().parents[2]
SIDE_PX = 1024


def capture(bin_dir, folder):
    """The 96-LED dome's rig with a 1 MP camera over the same field, and a dark + each-LED recipe."""
    rig_text = (SOURCE_DIR / "config/rigs/sim-dome-96.yaml").read_text()
    rig_text = rig_text.replace("width: 384", f"width: {SIDE_PX}").replace("height: 384", f"height: {SIDE_PX}")
    rig_text = rig_text.replace("pixel_pitch_mm: 0.1 ", f"pixel_pitch_mm: {38.4 / SIDE_PX} ")
    (folder / "rig.yaml").write_text(rig_text)
    (folder / "recipe.yaml").write_text(
        "recipe: {name: open-run-bench, rig: rig.yaml}\n"
        "capture:\n  exposure_us: 16000\n  steps:\n    - dark: {count: 1}\n    - each_led: {leds: all, level: 1.0}\n")
    run = folder / "run"
    subprocess.run([str(bin_dir / "photorig"), "run", str(folder / "recipe.yaml"), "--out", str(run)],
                   check=True, capture_output=True)
    return run


def with_photorig(run):
    return photorig.open_run(str(run)).frames()


def with_opencv(run):
    files = sorted((run / "frames").glob("*.png"))
    return [cv2.imread(str(f), cv2.IMREAD_UNCHANGED) for f in files]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin-dir", type=Path, default=SOURCE_DIR / "build/bin")
    parser.add_argument("--run", type=Path, help="an existing run (default: capture one)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        run = args.run or capture(args.bin_dir, Path(scratch))
        best = {"photorig": float("inf"), "opencv": float("inf")}
        for _ in range(args.repeats):
            for name, read in [("photorig", with_photorig), ("opencv", with_opencv)]:
                start = time.perf_counter()
                read(run)
                best[name] = min(best[name], time.perf_counter() - start)
        ours, theirs = with_photorig(run), with_opencv(run)
        assert all(np.array_equal(a, b) for a, b in zip(ours, theirs)) and len(ours) == len(theirs)
        count, rows, cols = ours.shape
        print(f"{count} frames of {cols} x {rows}, best of {args.repeats}:")
        print(f"  photorig.open_run(...).frames(): {best['photorig'] * 1e3:8.1f} ms")
        print(f"  cv2.imread of each PNG:          {best['opencv'] * 1e3:8.1f} ms")
        print(f"  ratio photorig / opencv:         {best['photorig'] / best['opencv']:8.2f}")


if __name__ == "__main__":
    main()
