"""photorig.solve_brdf against `photorig solve brdf` on the same gonioreflectometer run: the same samples and fits."""

import json

import numpy as np
import pytest

import photorig
from conftest import as_written, capture, photorig_json, without_timings


@pytest.fixture(scope="module")
def gonio_run(tmp_path_factory):
    """The simulated gonioreflectometer's glossy sample (config/recipes/brdf-gonio.yaml), captured only."""
    return capture("brdf-gonio.yaml", tmp_path_factory.mktemp("gonio"))


def without_clock(report):
    """report.json less what the clock decides (provenance's date, the timings)."""
    return without_timings({key: as_written(value) for key, value in report.items() if key != "provenance"})


def test_same_samples_and_fits_as_the_cli(gonio_run, tmp_path):
    printed = photorig_json("solve", "brdf", "--run", gonio_run, "--out", tmp_path / "cli")
    solved = photorig.solve_brdf(photorig.open_run(str(gonio_run)), out=str(tmp_path / "module"))
    assert solved["directory"] == str(tmp_path / "module")
    # samples.csv holds the samples as written (the doubles' shortest round trip): the module's arrays are they.
    assert (tmp_path / "module/samples.csv").read_bytes() == (tmp_path / "cli/samples.csv").read_bytes()
    table = np.loadtxt(tmp_path / "cli/samples.csv", delimiter=",", skiprows=1, usecols=range(12))
    np.testing.assert_array_equal(solved["wi"], table[:, 0:3])
    np.testing.assert_array_equal(solved["wo"], table[:, 3:6])
    np.testing.assert_array_equal(solved["value"], table[:, 6:9])
    np.testing.assert_array_equal(solved["sigma"], table[:, 9:12])
    report = json.loads((tmp_path / "cli/report.json").read_text())
    assert without_clock(solved["summary"]) == without_clock(report)
    assert as_written(printed["candidates"]) == report["candidates"]
    # The simulated sample is Blinn-Phong, rho_d 0.4, k_s 0.5, e 20 (the recipe's header).
    assert solved["model"] == report["chosen"] == "blinn_phong"
    chosen = report["candidates"][[c["model"] for c in report["candidates"]].index("blinn_phong")]
    assert without_timings(as_written(solved["parameters"])) == without_timings(chosen)
    assert len(solved["value"]) == report["samples"] >= 40
    assert solved["summary"]["provenance"]["options"] == report["provenance"]["options"]


def test_bad_options_raise_the_solvers_message(gonio_run, tmp_path):
    with pytest.raises(ValueError, match="weighted"):
        photorig.solve_brdf(str(gonio_run), loss="squared", out=str(tmp_path / "never"))
    with pytest.raises(ValueError, match="reference"):
        photorig.solve_brdf(str(gonio_run), calibration="target", out=str(tmp_path / "never"))
