"""photorig.solve_tomography against `photorig solve tomography` on the same scan: bit for bit."""

import json

import numpy as np
import pytest

import photorig
from conftest import SOURCE_DIR, without_timings


def read_nrrd(path):
    """The raw little-endian float volume solvers/tomography/nrrd.cpp writes, as (nz, ny, nx)."""
    data = path.read_bytes()
    header, _, body = data.partition(b"\n\n")
    fields = dict(line.split(": ", 1) for line in header.decode().splitlines()[1:] if ": " in line)
    assert (fields["type"], fields["endian"], fields["encoding"]) == ("float", "little", "raw")
    nx, ny, nz = map(int, fields["sizes"].split())
    return np.frombuffer(body, dtype="<f4").reshape(nz, ny, nx)


@pytest.fixture(scope="module")
def scan(tmp_path_factory, cli):
    run = tmp_path_factory.mktemp("runs") / "tomography"
    cli("run", SOURCE_DIR / "config/recipes/tomography.yaml", "--out", run)
    return run


def test_same_volume_as_the_cli(scan, cli, tmp_path):
    cli("solve", "tomography", "--run", scan, "--method", "sirt", "--no-held-out", "--out", tmp_path)
    solved = photorig.solve_tomography(str(scan), method="sirt", held_out=False)
    expected = read_nrrd(tmp_path / "volume.nrrd")
    assert solved["volume"].shape == expected.shape == (8, 64, 64)
    np.testing.assert_array_equal(solved["volume"], expected)
    report = json.loads((tmp_path / "report.json").read_text())
    for key in ["iterations", "stop_reason", "residual_history", "volume", "absorbance"]:
        assert without_timings(solved["summary"][key]) == without_timings(report[key]), key
    assert solved["summary"]["centre_of_rotation"]["offset_mm"] == report["centre_of_rotation"]["offset_mm"]


def test_bad_options_raise_the_solvers_message(scan):
    with pytest.raises(ValueError, match="max_iterations"):
        photorig.solve_tomography(str(scan), max_iterations=0)
    with pytest.raises(ValueError, match="sirt"):
        photorig.solve_tomography(str(scan), method="fbp")
