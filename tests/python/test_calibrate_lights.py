"""photorig.calibrate_lights against `photorig calibrate lights --run` on the same run: the same lights, bit for bit."""

import json
import subprocess

import numpy as np
import pytest

import photorig
from conftest import BIN_DIR, SOURCE_DIR, capture, photorig as photorig_cli, photorig_json


@pytest.fixture(scope="module")
def mirror_run(tmp_path_factory):
    """The simulated dome's light calibration: a chrome sphere of radius 17 mm under each LED, captured only."""
    return capture("light-calibration.yaml", tmp_path_factory.mktemp("mirror"))


def same_files(ours, theirs, names):
    for name in names:
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name


def test_same_lights_as_the_cli(mirror_run, tmp_path):
    printed = photorig_json("calibrate", "lights", "--run", mirror_run, "--radius-mm", 17, "--out", tmp_path / "cli")
    calibrated = photorig.calibrate_lights(photorig.open_run(str(mirror_run)), sphere_radius_mm=17,
                                           out=str(tmp_path / "module"))
    assert calibrated["directory"] == str(tmp_path / "module")
    report = json.loads((tmp_path / "cli/report.json").read_text())
    # report.json's numbers read back as the doubles written: equal is bit for bit.
    np.testing.assert_array_equal(calibrated["direction"], [light["direction"] for light in report["lights"]])
    np.testing.assert_array_equal(calibrated["uncertainty_deg"], [light["uncertainty_deg"] for light in report["lights"]])
    assert calibrated["usable"].shape == (48,) and calibrated["usable"].all()
    assert "rgb_intensity" not in calibrated  # no white-sphere images
    same_files(tmp_path / "module", tmp_path / "cli", ["lights.lp", "light_directions.txt", "light_intensities.txt",
                                                       "report.json"])
    summary = calibrated["summary"]
    assert summary == {key: value for key, value in printed.items() if key != "out"}
    assert summary["success"] and summary["sphere"]["source"] == "highlights" and summary["unusable"] == 0
    # The simulator's true directions: found to a quarter of a degree (0.11 deg on average).
    truth = np.loadtxt(mirror_run / "ground_truth/light_directions.txt")
    angles = np.degrees(np.arccos(np.clip((calibrated["direction"] * truth).sum(axis=1), -1, 1)))
    assert angles.mean() < 0.2 and angles.max() < 0.3


@pytest.fixture(scope="module")
def white_run(tmp_path_factory):
    """The demo's sphere (the mirror sphere's place and radius) painted a uniform white, captured only."""
    folder = tmp_path_factory.mktemp("white")
    recipe = (SOURCE_DIR / "config/recipes/ps-sphere.yaml").read_text()
    recipe = recipe.replace("rig: ../rigs/", f"rig: {SOURCE_DIR}/config/rigs/")
    recipe = recipe.replace("{pattern: checker, low: 0.35, high: 0.85, period_mm: 6}", "{pattern: uniform, high: 0.8}")
    assert "pattern: uniform" in recipe
    (folder / "white.yaml").write_text(recipe)
    run = folder / "run"
    photorig_cli("run", folder / "white.yaml", "--no-solve", "--out", run)
    return run


def light_frames(run):
    meta = photorig.open_run(str(run)).metadata("light")
    return [str(run / name) for _, name in sorted(zip(meta["led"], meta["file"]))]


def test_white_sphere_intensities_as_the_cli(mirror_run, white_run, cli, tmp_path):
    white = light_frames(white_run)
    cli("calibrate", "lights", "--run", mirror_run, "--radius-mm", 17, "--white-images", *white,
        "--out", tmp_path / "cli")
    calibrated = photorig.calibrate_lights(str(mirror_run), sphere_radius_mm=17, white_images=white,
                                           out=str(tmp_path / "module"))
    report = json.loads((tmp_path / "cli/report.json").read_text())
    rgb = np.array([light["rgb_intensity"] for light in report["lights"]])
    np.testing.assert_array_equal(calibrated["rgb_intensity"], rgb)
    np.testing.assert_array_equal(calibrated["intensity"], rgb.mean(axis=1))
    assert np.isfinite(rgb).all() and rgb.min() > 0
    assert calibrated["summary"]["unusable_intensities"] == 0
    assert max(light["intensity_model_error"] for light in report["lights"]) < 0.05
    same_files(tmp_path / "module", tmp_path / "cli", ["light_intensities.txt", "report.json"])


def test_a_textured_sphere_gives_no_intensities(mirror_run, demo_run, tmp_path):
    # The demo's sphere is checkered (albedo 0.35-0.85): as a white target its shading is no matte surface's.
    done = subprocess.run([str(BIN_DIR / "photorig"), "calibrate", "lights", "--run", str(mirror_run), "--radius-mm",
                           "17", "--white-images", *light_frames(demo_run), "--out", str(tmp_path / "cli")],
                          capture_output=True, text=True)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "48 of 48 intensities unusable" in done.stdout + done.stderr
    assert "departs from a matte surface's" in done.stdout + done.stderr
    calibrated = photorig.calibrate_lights(str(mirror_run), sphere_radius_mm=17, white_images=light_frames(demo_run),
                                           out=str(tmp_path / "module"))
    assert not calibrated["summary"]["success"] and calibrated["summary"]["unusable_intensities"] == 48
    assert np.isnan(calibrated["rgb_intensity"]).all()
    assert np.isfinite(calibrated["direction"]).all()  # the directions stand
    report = json.loads((tmp_path / "cli/report.json").read_text())
    assert not any(light["intensity_usable"] for light in report["lights"])


def test_a_calibrated_rig_is_a_new_file(mirror_run, tmp_path):
    rig = str(SOURCE_DIR / "config/rigs/sim-dome.yaml")
    out_rig = tmp_path / "calibrated.yaml"
    first = photorig.calibrate_lights(str(mirror_run), sphere_radius_mm=17, rig=rig, out_rig=str(out_rig),
                                      out=str(tmp_path / "first"))
    assert first["summary"]["success"] and first["summary"]["out_rig"] == str(out_rig)
    assert "led_direction_error_deg" not in out_rig.read_text()
    # Never over an existing file: the calibration is returned, failed, saying why.
    again = photorig.calibrate_lights(str(mirror_run), sphere_radius_mm=17, rig=rig, out_rig=str(out_rig),
                                      out=str(tmp_path / "again"))
    assert not again["summary"]["success"] and "exists" in again["summary"]["message"]
    np.testing.assert_array_equal(again["direction"], first["direction"])


def test_bad_options_raise_the_solvers_message(mirror_run, tmp_path):
    out = str(tmp_path / "never")
    for radius_mm in (-1, float("inf")):
        with pytest.raises(ValueError, match="sphere radius_mm must be finite and >= 0"):
            photorig.calibrate_lights(str(mirror_run), sphere_radius_mm=radius_mm, out=out)
    with pytest.raises(ValueError, match="the sphere circle needs a positive radius"):
        photorig.calibrate_lights(str(mirror_run), circle=(192, 192, 0), out=out)
    with pytest.raises(ValueError, match="needs both the rig to copy and the file to write"):
        photorig.calibrate_lights(str(mirror_run), out_rig=str(tmp_path / "rig.yaml"), out=out)
    with pytest.raises(ValueError, match="pinhole camera needs positive fx_px and fy_px"):
        photorig.calibrate_lights(str(mirror_run), camera="pinhole", out=out)
    with pytest.raises(ValueError, match="camera must be orthographic or pinhole"):
        photorig.calibrate_lights(str(mirror_run), camera="fisheye", out=out)
    with pytest.raises(ValueError, match="missing.png: cannot read the white-sphere image"):
        photorig.calibrate_lights(str(mirror_run), white_images=[str(tmp_path / "missing.png")], out=out)
    assert not (tmp_path / "never").exists()
