"""photorig.calibrate_color against `photorig calibrate color` on the same chart: the same model, bit for bit."""

import json

import cv2
import numpy as np
import pytest

import photorig
from conftest import without_timings

def as_floats(values):
    """A report's per-patch list, null (a patch not used) as NaN."""
    return np.array([np.nan if value is None else value for value in values])


def test_same_model_as_the_cli(cli, tmp_path):
    cli("calibrate", "color", "--sim-camera", "nikon-5100", "--out", tmp_path / "cli")
    stages = []
    calibrated = photorig.calibrate_color(sim_camera="nikon-5100", out=str(tmp_path / "module"),
                                          progress=lambda stage, done, total: stages.append((stage, done, total)))
    assert calibrated["directory"] == str(tmp_path / "module")
    # The same rendering, model files (17 significant digits: bit for bit) and corrected image.
    for name in ["chart.png", "dark.png", "model.json", "model.yaml", "corrected_srgb.png"]:
        assert (tmp_path / "module" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    report = json.loads((tmp_path / "cli/report.json").read_text())
    summary = calibrated["summary"]
    assert summary == json.loads((tmp_path / "module/report.json").read_text())
    for key in ["image", "dark"]:  # each names its own folder's rendering
        assert summary.pop(key) == str(tmp_path / "module" / f"{key if key == 'dark' else 'chart'}.png")
        report.pop(key)
    assert without_timings(summary) == without_timings(report)

    model = json.loads((tmp_path / "cli/model.json").read_text())
    assert calibrated["model"] == model["model"] == report["chosen"]
    np.testing.assert_array_equal(calibrated["coefficients"], model["coefficients"])
    assert calibrated["input_scale"] == model["input_scale"]
    np.testing.assert_array_equal(calibrated["white_xyz"], model["white_xyz"])
    chosen = next(entry for entry in report["models"] if entry["model"] == report["chosen"])
    np.testing.assert_array_equal(calibrated["training_de"], as_floats(chosen["training_de"]))
    np.testing.assert_array_equal(calibrated["held_out_de"], as_floats(chosen["held_out_de"]))
    np.testing.assert_array_equal(calibrated["patch_rgb"], [patch["rgb"] for patch in report["patches"]])
    assert calibrated["patch_rgb"].shape == (24, 3) and np.nanmean(calibrated["held_out_de"]) < 3.0
    assert any(stage == "colour fits" and done == total > 0 for stage, done, total in stages)


def test_a_capture_and_candidates_as_the_cli(cli, tmp_path):
    # The CLI's rendering as a capture on disk, fitted to two candidates by CIEDE2000.
    cli("calibrate", "color", "--sim-camera", "canon-5d-mark-ii", "--illuminant", "A", "--out", tmp_path / "render")
    chart, dark = tmp_path / "render/chart.png", tmp_path / "render/dark.png"
    cli("calibrate", "color", "--image", chart, "--dark", dark, "--illuminant", "A", "--loss", "ciede2000",
        "--models", "linear,root-poly-2", "--out", tmp_path / "cli")
    calibrated = photorig.calibrate_color(str(chart), dark=str(dark), illuminant="A", loss="ciede2000",
                                          models=["linear", "root-poly-2"], out=str(tmp_path / "module"))
    for name in ["model.json", "corrected_srgb.png"]:
        assert (tmp_path / "module" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    report = json.loads((tmp_path / "cli/report.json").read_text())
    assert [entry["model"] for entry in calibrated["summary"]["models"]] == ["linear", "root-poly-2"]
    assert without_timings(calibrated["summary"]) == without_timings(report)
    assert calibrated["summary"]["illuminant"] == "A"


def test_a_chart_not_found_returns_why(tmp_path):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((240, 320, 3), 128, np.uint8))
    calibrated = photorig.calibrate_color(str(blank), out=str(tmp_path / "out"))
    assert calibrated["model"] is None and "coefficients" not in calibrated
    assert calibrated["summary"]["chosen"] is None and calibrated["summary"]["termination"] != "success"
    assert (tmp_path / "out/report.json").exists() and not (tmp_path / "out/model.json").exists()


def test_bad_options_raise_the_solvers_message(tmp_path):
    out = str(tmp_path / "never")
    with pytest.raises(ValueError, match="max_condition_number must be > 1"):
        photorig.calibrate_color(sim_camera="nikon-5100", max_condition_number=1.0, out=out)
    with pytest.raises(ValueError, match="selection_tolerance must be >= 0"):
        photorig.calibrate_color(sim_camera="nikon-5100", selection_tolerance=-0.1, out=out)
    with pytest.raises(ValueError, match="no candidate models"):
        photorig.calibrate_color(sim_camera="nikon-5100", models=[], out=out)
    with pytest.raises(ValueError, match=r"unknown colour model 'cubic' \(known: linear"):
        photorig.calibrate_color(sim_camera="nikon-5100", models=["cubic"], out=out)
    with pytest.raises(ValueError, match="loss must be xyz or ciede2000"):
        photorig.calibrate_color(sim_camera="nikon-5100", loss="l1", out=out)
    with pytest.raises(ValueError, match="unknown camera 'nikon'"):
        photorig.calibrate_color(sim_camera="nikon", out=out)
    with pytest.raises(ValueError, match="give exactly one of a chart image and a simulated camera"):
        photorig.calibrate_color(out=out)
    with pytest.raises(ValueError, match="chart_roi 1,2,3: 3 numbers"):
        photorig.calibrate_color(sim_camera="nikon-5100", chart_roi="1,2,3", out=out)
    assert not (tmp_path / "never").exists()


def test_unreadable_captures_raise_before_writing(tmp_path):
    with pytest.raises(ValueError, match="missing.png"):
        photorig.calibrate_color(str(tmp_path / "missing.png"), out=str(tmp_path / "out"))
    mosaic = tmp_path / "raw.png"
    raw = np.zeros((64, 64), np.uint16)
    raw[0::2, 0::2], raw[1::2, 1::2], raw[0::2, 1::2], raw[1::2, 0::2] = 4000, 1000, 2000, 2000  # R, B, G, G
    cv2.imwrite(str(mosaic), raw)
    with pytest.raises(ValueError, match="looks like a raw Bayer mosaic"):
        photorig.calibrate_color(str(mosaic), out=str(tmp_path / "out"))
    assert not (tmp_path / "out").exists()
