"""photorig.solve_ps against `photorig solve ps` on the same run: bit for bit."""

import json

import cv2
import numpy as np
import pytest

import photorig
from conftest import SOURCE_DIR


def read_tiff(path):
    """A float TIFF as the pipeline wrote it: three channels in the file's R, G, B order (x, y, z)."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    return image[..., ::-1] if image.ndim == 3 else image


@pytest.mark.parametrize("method", ["auto", "lambertian"])
def test_same_maps_as_the_cli(demo_run, cli, tmp_path, method):
    out = tmp_path / method
    cli("solve", "ps", "--run", demo_run, "--method", method, "--out", out)
    stages = []
    solved = photorig.solve_ps(photorig.open_run(str(demo_run)), method=method,
                               progress=lambda stage, done, total: stages.append((stage, done, total)))
    for name in ["normals", "albedo", "confidence", "depth"]:
        expected = read_tiff(out / f"{name}.tiff")
        assert solved[name].shape == expected.shape, name
        # NaN where unsolved in both, and the max abs difference elsewhere 0.
        np.testing.assert_array_equal(solved[name], expected, err_msg=name)
    report = json.loads((out / "report.json").read_text())
    summary = solved["summary"]
    assert summary["method"] == report["method"] == method
    assert summary["pixels"] == report["pixels"] and summary["pixels"]["solved"] > 50000
    assert summary["ground_truth"] == report["ground_truth"]
    assert any(done == total > 0 for _, done, total in stages)


def test_a_rig_given_replaces_the_runs_lights(demo_run):
    # The rig the demo was captured with: the same lights, so the same normals.
    as_captured = photorig.solve_ps(str(demo_run), method="lambertian")
    with_rig = photorig.solve_ps(str(demo_run), method="lambertian", rig=str(SOURCE_DIR / "config/rigs/sim-dome.yaml"))
    np.testing.assert_array_equal(with_rig["normals"], as_captured["normals"])
    assert with_rig["summary"]["provenance"]["options"]["loading"]["rig"].endswith("sim-dome.yaml")
    # Another dome's rig is refused, naming it and what does not match.
    with pytest.raises(Exception, match="96 LEDs"):
        photorig.solve_ps(str(demo_run), rig=str(SOURCE_DIR / "config/rigs/sim-dome-96.yaml"))


def test_bad_options_raise_the_solvers_message(demo_run):
    with pytest.raises(ValueError, match="lambertian"):
        photorig.solve_ps(str(demo_run), method="lambert")
    with pytest.raises(ValueError, match="shadow_threshold_sigma"):
        photorig.solve_ps(str(demo_run), shadow_threshold_sigma=-1.0)


def test_progress_callback_errors_surface(demo_run):
    def fail(stage, done, total):
        raise KeyError("stop")

    with pytest.raises(KeyError):
        photorig.solve_ps(str(demo_run), method="lambertian", progress=fail)
