"""photorig.calibrate_leds against `photorig calibrate leds` on the same run: the same positions, bit for bit."""

import json

import numpy as np
import pytest

import photorig
from conftest import SOURCE_DIR, capture, photorig_json

SPHERES = [(-30, -20), (30, -20), (0, 35)]  # config/recipes/led-positions.yaml's balls, mm


@pytest.fixture(scope="module")
def spheres_run(tmp_path_factory):
    """The simulated near-LED dome over three chrome spheres of radius 17 mm, one frame per LED, captured only."""
    return capture("led-positions.yaml", tmp_path_factory.mktemp("near"))


def test_same_positions_as_the_cli(spheres_run, tmp_path):
    flags = [arg for x, y in SPHERES for arg in ("--sphere", f"{x},{y}")]
    printed = photorig_json("calibrate", "leds", "--run", spheres_run, *flags, "--radius-mm", 17, "--out", tmp_path / "cli")
    calibrated = photorig.calibrate_leds(photorig.open_run(str(spheres_run)), spheres=SPHERES, sphere_radius_mm=17,
                                         out=str(tmp_path / "module"))
    assert calibrated["directory"] == str(tmp_path / "module")
    report = json.loads((tmp_path / "cli/report.json").read_text())
    leds = report["leds"]
    assert calibrated["usable"].tolist() == [led["usable"] for led in leds] and calibrated["usable"].all()
    # report.json's numbers read back as the doubles written: equal is bit for bit.
    np.testing.assert_array_equal(calibrated["position_mm"], [led["position_mm"] for led in leds])
    np.testing.assert_array_equal(calibrated["rms_ray_distance_mm"], [led["rms_ray_distance_mm"] for led in leds])
    np.testing.assert_array_equal(calibrated["predicted_sigma_mm"], [led["predicted_sigma_mm"] for led in leds])
    assert (tmp_path / "module/report.json").read_bytes() == (tmp_path / "cli/report.json").read_bytes()
    summary = calibrated["summary"]
    assert summary == {key: value for key, value in printed.items() if key != "out"}
    # Against the simulator's true positions, as the report measures them.
    truth = np.loadtxt(spheres_run / "ground_truth/light_positions.txt")
    errors = np.linalg.norm(calibrated["position_mm"] - truth, axis=1)
    assert errors.mean() == pytest.approx(summary["mean_error_vs_truth_mm"], rel=1e-12)
    assert summary["success"] and errors.max() < 5.0


def test_bad_options_raise_the_solvers_message(spheres_run, tmp_path):
    out = str(tmp_path / "never")
    with pytest.raises(ValueError, match="LED positions need two or more spheres"):
        photorig.calibrate_leds(str(spheres_run), spheres=SPHERES[:1], sphere_radius_mm=17, out=out)
    with pytest.raises(ValueError, match="the spheres' radius_mm must be > 0"):
        photorig.calibrate_leds(str(spheres_run), spheres=SPHERES, sphere_radius_mm=0, out=out)
    with pytest.raises(ValueError, match=r"\(x, y\) or \(x, y, z\) in mm, not 4 numbers"):
        photorig.calibrate_leds(str(spheres_run), spheres=[(0, 0, 0, 0), (1, 1)], sphere_radius_mm=17, out=out)
    with pytest.raises(ValueError, match="needs both the rig to copy and the file to write"):
        photorig.calibrate_leds(str(spheres_run), spheres=SPHERES, sphere_radius_mm=17, rig=str(SOURCE_DIR /
                                "config/rigs/sim-dome-near.yaml"), out=out)
    assert not (tmp_path / "never").exists()
