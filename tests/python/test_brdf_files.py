"""photorig.read_merl, write_merl and eval_brdf against the file's bytes and `photorig brdf eval`."""

import json
import math

import numpy as np
import pytest

import photorig
from conftest import as_written, without_timings

SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])  # MERL's channel scales (merl.h)


def direction(theta_deg, phi_deg):
    """As `photorig brdf eval` turns degrees into a unit vector."""
    t, p = theta_deg * (math.pi / 180.0), phi_deg * (math.pi / 180.0)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    """A glossy table over MERL's bins, a block of its cells unmeasured, written by write_merl."""
    theta_h = (np.arange(90) + 0.5) / 90.0
    values = np.empty((3, 90, 90, 180))
    for c, albedo in enumerate([0.2, 0.3, 0.4]):
        values[c] = albedo / math.pi + 2.0 * np.exp(-((theta_h / 0.1) ** 2))[:, None, None]
    values[:, 80:85, 10:20, :] = np.nan  # grazing half vectors, away from the configurations below
    path = tmp_path_factory.mktemp("brdf") / "glossy.binary"
    photorig.write_merl(str(path), values)
    return path, values


def test_read_merl_is_the_files_cells(table):
    path, values = table
    raw = np.fromfile(path, dtype="<f8", offset=12).reshape(3, 90, 90, 180)
    assert tuple(np.fromfile(path, dtype="<i4", count=3)) == (90, 90, 180)
    expected = np.where(raw < 0, np.nan, raw * SCALE[:, None, None, None])
    read = photorig.read_merl(str(path))
    np.testing.assert_array_equal(read, expected)
    np.testing.assert_allclose(read, values, rtol=1e-12)


def test_eval_is_the_clis(table, cli):
    path, _ = table
    configurations = [((30, 0), (30, 180)), ((45, 90), (20, 10)), ((10, 0), (60, 300))]
    wi = np.array([direction(*i) for i, _ in configurations])
    wo = np.array([direction(*o) for _, o in configurations])
    ours = photorig.eval_brdf(str(path), wi, wo)
    for row, (i, o) in zip(ours, configurations):
        doc = json.loads(cli("brdf", "eval", path, "--wi", *i, "--wo", *o, "--json"))
        assert list(row) == doc["f_r"]
    below = photorig.eval_brdf(str(path), np.array([[0.0, 0.0, -1.0]]), np.array([[0.0, 0.0, 1.0]]))
    assert np.isnan(below).all()


def test_bad_files_raise_the_readers_message(tmp_path):
    short = tmp_path / "short.binary"
    short.write_bytes(b"\0" * 100)
    with pytest.raises(ValueError, match="short.binary"):
        photorig.read_merl(str(short))
    with pytest.raises(ValueError, match=r"\(3, 90, 90, 180\)"):
        photorig.write_merl(str(tmp_path / "x.binary"), np.zeros((3, 90, 90)))
    # A negative value would read back as a cell not measured; a name other than .binary would not read back at all.
    negative = np.full((3, 90, 90, 180), 0.1)
    negative[1, 2, 3, 4] = -0.5
    with pytest.raises(ValueError, match=r"values\[1, 2, 3, 4\] is -0.5.*not negative"):
        photorig.write_merl(str(tmp_path / "neg.binary"), negative)
    with pytest.raises(ValueError, match="a MERL table is written as a .binary file"):
        photorig.write_merl(str(tmp_path / "table.png"), np.full((3, 90, 90, 180), 0.1))
    assert not (tmp_path / "neg.binary").exists() and not (tmp_path / "table.png").exists()


def test_a_measurement_that_reflects_nothing_is_not_fitted(tmp_path):
    """A black table, or samples whose values are all at or below 0, once fitted Lambertian with success."""
    with pytest.raises(ValueError, match="R plane .* has no value above 0: it reflects nothing to fit"):
        photorig.fit_brdf(np.zeros((3, 90, 90, 180)), samples=2000)
    dark = tmp_path / "dark.csv"
    lines = ["wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b"]
    for theta_o in range(5, 80, 5):
        wi, wo = direction(30, 180), direction(theta_o, 0)
        lines.append(",".join(repr(float(v)) for v in [*wi, *wo, 0.1, 0.1, -0.01, 0.01, 0.01, 0.01]))
    dark.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match="no sample has a positive B value"):
        photorig.fit_brdf(str(dark))


def test_fit_is_the_clis(table, cli, tmp_path):
    path, values = table
    cli("brdf", "fit", path, "--samples", 2000, "--out", tmp_path / "fit")
    report = json.loads((tmp_path / "fit/report.json").read_text())
    fitted = photorig.fit_brdf(str(path), samples=2000)
    assert fitted["model"] == report["chosen"] and fitted["summary"]["reason"] == report["reason"]
    assert fitted["summary"]["cells"] == report["cells"] and fitted["summary"]["poor_fit"] == report["poor_fit"]
    for ours, theirs in zip(fitted["summary"]["candidates"], report["candidates"]):
        assert {k: ours[k] for k in ["model", "bic", "all_cells_log_rms"]} == \
               {k: theirs[k] for k in ["model", "bic", "all_cells_log_rms"]}
    chosen = next(c for c in report["candidates"] if c["model"] == report["chosen"])
    for key in ["diffuse", "specular", "shape"]:
        assert fitted["parameters"][key] == chosen[key], key
    # The array read_merl gives fits as its file does (the file stores float64, rescaled per channel).
    from_array = photorig.fit_brdf(values, samples=2000)
    assert from_array["model"] == fitted["model"]
    np.testing.assert_allclose(from_array["parameters"]["shape"], fitted["parameters"]["shape"], rtol=1e-6)


def test_fit_options_raise_the_solvers_message(table):
    path, _ = table
    with pytest.raises(ValueError, match="a table carries no deviations"):
        photorig.fit_brdf(str(path), loss="weighted")
    with pytest.raises(ValueError, match="samples must be at least 100"):
        photorig.fit_brdf(str(path), samples=10)


@pytest.fixture(scope="module")
def samples_csv(tmp_path_factory):
    """A glossy material (Lambertian plus Blinn-Phong of exponent 60) over a gonioreflectometer's arcs, with 2 %
    deviations, as `photorig solve brdf` writes samples.csv (here without the origin columns)."""
    rows = []
    for theta_i in range(10, 75, 8):
        for phi_o in [0, 30, 150, 180]:
            for theta_o in range(5, 80, 3):
                wi, wo = np.array(direction(theta_i, 180)), np.array(direction(theta_o, phi_o))
                h = (wi + wo) / np.linalg.norm(wi + wo)
                f = np.array([0.3, 0.4, 0.5]) / math.pi + 0.4 * (60 + 2) / (2 * math.pi) * h[2] ** 60
                rows.append([*wi, *wo, *f, *(0.02 * f)])
    path = tmp_path_factory.mktemp("samples") / "samples.csv"
    lines = ["wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b"]
    lines += [",".join(repr(float(v)) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path, len(rows)


def test_samples_fit_is_the_clis(samples_csv, cli, tmp_path):
    path, count = samples_csv
    cli("brdf", "fit", path, "--out", tmp_path / "fit")
    report = json.loads((tmp_path / "fit/report.json").read_text())
    fitted = photorig.fit_brdf(str(path))
    summary = fitted["summary"]
    assert summary["format"] == "samples" and summary["loss"] == "weighted" and summary["samples"] == count
    # The CLI's report adds only the material it names; every fitted figure is the same double.
    assert without_timings(as_written(summary)) == without_timings({key: value for key, value in report.items() if key != "material"})
    assert fitted["model"] == report["chosen"] is not None
    chosen = next(c for c in report["candidates"] if c["model"] == fitted["model"])
    assert without_timings(as_written(fitted["parameters"])) == without_timings(chosen)
    # Noise-free samples of a Blinn-Phong lobe: its fit finds the exponent and the diffuse albedo.
    blinn_phong = next(c for c in summary["candidates"] if c["model"] == "blinn_phong")
    assert blinn_phong["shape"] == pytest.approx(60, rel=1e-6)
    np.testing.assert_allclose(blinn_phong["diffuse"], [0.3, 0.4, 0.5], rtol=1e-6)


def test_samples_fit_options_raise_the_solvers_message(samples_csv, tmp_path):
    path, _ = samples_csv
    with pytest.raises(ValueError, match="loss must be weighted or log"):
        photorig.fit_brdf(str(path), loss="l2")
    bad = tmp_path / "bad.csv"
    bad.write_text("theta,phi\n1,2\n")
    with pytest.raises(ValueError, match="the first line is not the header"):
        photorig.fit_brdf(str(bad))
