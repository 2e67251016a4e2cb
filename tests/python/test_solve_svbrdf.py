"""photorig.solve_svbrdf against `photorig solve svbrdf` on the same run: the same maps, bit for bit."""

import json

import cv2
import numpy as np
import pytest

import photorig
from conftest import capture


@pytest.fixture(scope="module")
def glossy_run(tmp_path_factory):
    """The simulated glossy sphere, captured only, and a mask of a block at its centre (a short solve)."""
    folder = tmp_path_factory.mktemp("glossy")
    run = capture("ps-shiny-sphere.yaml", folder)
    rows, cols = cv2.imread(str(run / "ground_truth/normals.tiff"), cv2.IMREAD_UNCHANGED).shape[:2]
    mask = np.zeros((rows, cols), np.uint8)
    mask[rows // 2 - 30:rows // 2 + 30, cols // 2 - 30:cols // 2 + 30] = 255
    cv2.imwrite(str(folder / "mask.png"), mask)
    return run, folder / "mask.png"


def test_same_maps_as_the_cli(glossy_run, cli, tmp_path):
    run, mask = glossy_run
    options = {"max_materials": 2, "held_out": 2}
    cli("solve", "svbrdf", "--run", run, "--mask", mask, "--max-materials", 2, "--held-out", 2, "--out", tmp_path / "cli")
    solved = photorig.solve_svbrdf(photorig.open_run(str(run)), mask=str(mask), out=str(tmp_path / "module"), **options)
    assert solved["directory"] == str(tmp_path / "module")
    albedo = cv2.imread(str(tmp_path / "cli/albedo.tiff"), cv2.IMREAD_UNCHANGED)
    # One channel for this monochrome run; NaN where not fitted in both.
    np.testing.assert_array_equal(solved["albedo"], albedo)
    np.testing.assert_array_equal(solved["material"], cv2.imread(str(tmp_path / "cli/material.png"), cv2.IMREAD_UNCHANGED))
    assert solved["flags"].shape == solved["material"].shape
    assert ((solved["flags"] == 0) == (solved["material"] != 255)).all()  # fitted pixels, and only they, have a material
    report = json.loads((tmp_path / "cli/report.json").read_text())
    summary = solved["summary"]
    assert summary["materials"] == report["materials"] and len(summary["materials"]) == 1
    assert summary["materials"][0]["model"] == "blinn_phong"
    assert summary["pixels"] == report["pixels"] and (solved["flags"] == 0).sum() == summary["pixels"]["fitted"] > 3000
    assert (tmp_path / "module/asset/asset.gltf").exists()


def test_bad_options_raise_the_solvers_message(glossy_run):
    run, _ = glossy_run
    with pytest.raises(ValueError, match=r"max_materials must be in \[1, 16\]"):
        photorig.solve_svbrdf(str(run), max_materials=0)
    with pytest.raises(ValueError, match="lambertian"):
        photorig.solve_svbrdf(str(run), method="lambert")
    with pytest.raises(ValueError, match="held_out_lights"):
        photorig.solve_svbrdf(str(run), held_out=-2)
