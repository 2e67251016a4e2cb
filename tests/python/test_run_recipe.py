"""photorig.run_recipe against `photorig run` of the same recipe: the same frames and normals."""

import cv2
import numpy as np
import pytest

import photorig
from conftest import SOURCE_DIR


def test_same_run_as_the_cli(demo_run, tmp_path):
    heard = []
    outcome = photorig.run_recipe(str(SOURCE_DIR / "config/recipes/ps-sphere.yaml"), out=str(tmp_path / "run"),
                                  progress=lambda stage, done, total: heard.append((stage, done, total)))
    assert outcome["capture"]["status"] == "complete" and outcome["capture"]["frames_written"] == 49
    assert [s["stage"] for s in outcome["solve_stages"]] == ["photometric_stereo"]
    assert outcome["solve_stages"][0]["ok"] and outcome["solve_stages"][0]["results"] == "results/ps"
    captured = [done for stage, done, _ in heard if stage == "capture"]
    assert captured == list(range(1, 50))
    ours, cli = photorig.open_run(outcome["directory"]), photorig.open_run(str(demo_run))
    np.testing.assert_array_equal(ours.frames(), cli.frames())
    for name in ["normals.tiff", "albedo.tiff", "depth.tiff"]:  # compared as stored, channel order alike
        np.testing.assert_array_equal(cv2.imread(str(tmp_path / "run/results/ps" / name), cv2.IMREAD_UNCHANGED),
                                      cv2.imread(str(demo_run / "results/ps" / name), cv2.IMREAD_UNCHANGED))


def test_bad_recipe_raises(tmp_path):
    recipe = tmp_path / "bad.yaml"
    recipe.write_text("recipe: {name: bad, rig: nowhere.yaml}\n")
    with pytest.raises(RuntimeError, match="nowhere.yaml"):
        photorig.run_recipe(str(recipe), out=str(tmp_path / "run"))
