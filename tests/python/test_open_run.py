"""photorig.open_run against the run's own files, read with OpenCV."""

import json
import shutil

import cv2
import numpy as np
import pytest

import photorig


def read_frame(run, record):
    return cv2.imread(str(run / record["file"]), cv2.IMREAD_UNCHANGED)


def test_manifest_is_the_files(demo_run):
    run = photorig.open_run(str(demo_run))
    stored = json.loads((demo_run / "manifest.json").read_text())
    assert run.manifest["run_id"] == stored["run_id"]
    assert run.manifest["frames"] == stored["frames"]


def test_frames_are_the_png_files(demo_run):
    run = photorig.open_run(str(demo_run))
    lights = [f for f in run.manifest["frames"] if f["kind"] == "light"]
    raw = run.frames("light")
    assert raw.dtype == np.uint16 and raw.shape[0] == len(lights) == 48
    for frame, record in zip(raw, lights):
        np.testing.assert_array_equal(frame, read_frame(demo_run, record))
    metadata = run.metadata("light")
    assert list(metadata["led"]) == [f["led"] for f in lights]
    assert list(metadata["exposure_us"]) == [f["exposure_us"] for f in lights]
    # A kind the run has no frame of gives the same columns, empty.
    none = run.metadata("flat")
    assert set(none) == set(metadata) and all(len(column) == 0 for column in none.values())


def test_one_frame_is_not_copied(demo_run):
    run = photorig.open_run(str(demo_run))
    frame = run.frame(3)
    assert not frame.flags.owndata and frame.base is not None
    np.testing.assert_array_equal(frame, read_frame(demo_run, run.manifest["frames"][3]))


def test_dark_subtracted(demo_run):
    run = photorig.open_run(str(demo_run))
    darks = run.frames("dark").astype(np.float32)
    expected = run.frames("light").astype(np.float32) - darks.sum(axis=0) / np.float32(len(darks))
    np.testing.assert_allclose(run.frames("light", dark_subtracted=True), expected, rtol=0, atol=1e-3)


def test_lights_and_camera(demo_run):
    run = photorig.open_run(str(demo_run))
    stored = run.manifest["lights"]
    np.testing.assert_array_equal(run.lights["direction"], np.array([led["direction"] for led in stored]))
    assert run.camera["projection"] == "orthographic"
    assert (run.camera["height_px"], run.camera["width_px"]) == run.frame(0).shape


def test_refusals(demo_run, tmp_path):
    run = photorig.open_run(str(demo_run))
    with pytest.raises(ValueError, match="kind must be"):
        run.frames("lights")
    with pytest.raises(ValueError, match="Bayer"):
        run.frames("light", demosaic="bilinear")
    with pytest.raises(IndexError):
        run.frame(len(run.manifest["frames"]))
    with pytest.raises(ValueError):
        photorig.open_run(str(tmp_path))
    # A path is a str or os.PathLike; None is a mistake, not a folder named "None".
    with pytest.raises(TypeError, match="run must be"):
        photorig.solve_ps(None)


def test_a_damaged_run_raises_value_error_naming_the_file(demo_run, tmp_path):
    damaged = tmp_path / "damaged"
    shutil.copytree(demo_run, damaged)
    manifest = damaged / "manifest.json"
    manifest.write_bytes(manifest.read_bytes()[: manifest.stat().st_size // 2])
    with pytest.raises(ValueError, match="manifest.json: corrupt manifest") as refused:
        photorig.open_run(str(damaged))
    assert "json.exception" not in str(refused.value)
