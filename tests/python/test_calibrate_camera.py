"""photorig.calibrate_camera against `photorig calibrate camera` on the same photographs: the same lens, bit for bit.

The photographs are drawn here with OpenCV through a known pinhole (no distortion), independently of the
simulator: a 9 x 6 board of 10 mm squares, 300 mm below a 384 x 384 camera, flat first, then tilted and moved
towards the image's corners."""

import json
import math

import cv2
import numpy as np
import pytest

import photorig
from conftest import SOURCE_DIR, photorig_json

FX, CX, DISTANCE_MM, SIZE = 716.55, 191.5, 300.0, 384
RIG = str(SOURCE_DIR / "config/rigs/sim-dome.yaml")  # an orthographic 384 x 384 camera


def rotation(tilt_x_deg, tilt_y_deg, spin_deg):
    rx, ry, rz = (math.radians(a) for a in (tilt_x_deg, tilt_y_deg, spin_deg))
    x = np.array([[1, 0, 0], [0, math.cos(rx), -math.sin(rx)], [0, math.sin(rx), math.cos(rx)]])
    y = np.array([[math.cos(ry), 0, math.sin(ry)], [0, 1, 0], [-math.sin(ry), 0, math.cos(ry)]])
    z = np.array([[math.cos(rz), -math.sin(rz), 0], [math.sin(rz), math.cos(rz), 0], [0, 0, 1]])
    return x @ y @ z


def photograph(tilt_x, tilt_y, spin, centre_mm, scale=4):
    """The board (its centre at centre_mm on the plane, turned about it) through the pinhole, drawn at `scale` times
    the resolution and averaged down, as a sensor integrates each pixel."""
    mm = 8  # texture pixels per mm
    border, cols, rows = 8, 10, 7  # squares
    width_mm, height_mm = cols * 10 + 2 * border, rows * 10 + 2 * border
    texture = np.full((height_mm * mm, width_mm * mm), int(0.85 * 255), np.uint8)
    for r in range(rows):
        for c in range(cols):
            if (r + c) % 2 == 0:
                y0, x0 = (border + 10 * r) * mm, (border + 10 * c) * mm
                texture[y0:y0 + 10 * mm, x0:x0 + 10 * mm] = int(0.05 * 255)
    # Texture pixel (u, v) -> board mm, centred: x = u / mm - width / 2, y = v / mm - height / 2.
    to_board = np.array([[1 / mm, 0, -width_mm / 2], [0, 1 / mm, -height_mm / 2], [0, 0, 1]])
    r = rotation(tilt_x, tilt_y, spin)
    t = np.array([centre_mm[0], centre_mm[1], DISTANCE_MM])
    k = np.array([[FX * scale, 0, (CX + 0.5) * scale - 0.5], [0, FX * scale, (CX + 0.5) * scale - 0.5], [0, 0, 1]])
    homography = k @ np.column_stack([r[:, 0], r[:, 1], t]) @ to_board
    big = cv2.warpPerspective(texture, homography, (SIZE * scale, SIZE * scale), flags=cv2.INTER_LINEAR,
                              borderValue=int(0.3 * 255))
    return cv2.resize(big, (SIZE, SIZE), interpolation=cv2.INTER_AREA)


POSES = [(0, 0, 0, (0, 0)), (35, 0, 0, (0, 0)), (-35, 0, 0, (0, 0)), (0, 35, 0, (0, 0)), (0, -35, 0, (0, 0)),
         (20, 20, 0, (24, 30)), (20, -20, 0, (-24, 30)), (-20, 20, 0, (24, -30)), (-20, -20, 0, (-24, -30)),
         (25, 25, 15, (0, 0))]


@pytest.fixture(scope="module")
def boards(tmp_path_factory):
    folder = tmp_path_factory.mktemp("boards")
    paths = []
    for i, pose in enumerate(POSES):
        path = folder / f"board{i}.png"
        cv2.imwrite(str(path), photograph(*pose))
        paths.append(str(path))
    return paths


def test_same_lens_as_the_cli(boards, tmp_path):
    printed = photorig_json("calibrate", "camera", "--images", *boards, "--board", "9x6", "--square-mm", 10,
                            "--plane-image", 0, "--rig", RIG, "--out-rig", tmp_path / "cli.yaml")
    calibrated = photorig.calibrate_camera(boards, board=(9, 6), square_mm=10, plane_image=0, rig=RIG,
                                           out_rig=str(tmp_path / "module.yaml"))
    summary = calibrated["summary"]
    assert summary["termination"] == "success" and calibrated["out_rig"] == str(tmp_path / "module.yaml")
    # The CLI's document less what names its own run: the same doubles, and the same rig but its date. A
    # candidate the corners barely determine (k3 on this narrow lens) may differ in its last digits between
    # processes; the lens kept is the same to the bit.
    ignore = {"out_rig", "timings_ms", "command", "ok", "exit_code", "candidates", "distortion_reason"}
    assert {k: v for k, v in summary.items() if k not in ignore} == {k: v for k, v in printed.items() if k not in ignore}
    for ours, theirs in zip(summary["candidates"], printed["candidates"], strict=True):
        assert ours["model"] == theirs["model"]
        assert ours["bic"] == pytest.approx(theirs["bic"], rel=1e-12) and ours["rms_px"] == pytest.approx(theirs["rms_px"], rel=1e-12)
    same = [line for line in (tmp_path / "cli.yaml").read_text().splitlines() if "date:" not in line]
    assert [line for line in (tmp_path / "module.yaml").read_text().splitlines() if "date:" not in line] == same
    # Against the lens the photographs were drawn through: a distortion-free one, chosen as such or as k1.
    lens = summary["lens"]
    assert calibrated["distortion_model"] in ("none", "k1")
    assert lens["fx_px"] == pytest.approx(FX, rel=0.005) and lens["fy_px"] == pytest.approx(FX, rel=0.005)
    assert lens["cx_px"] == pytest.approx(CX, abs=1.0) and lens["cy_px"] == pytest.approx(CX, abs=1.0)
    assert lens["distance_mm"] == pytest.approx(DISTANCE_MM, rel=0.01)
    assert summary["corner_reach"] > 0.6 and summary["rms_px"] < 0.3


def test_bad_options_and_unsupported_photographs(boards, tmp_path):
    out = str(tmp_path / "never.yaml")
    with pytest.raises(ValueError, match="at least 3 x 3 inner corners"):
        photorig.calibrate_camera(boards, board=(2, 6), square_mm=10, rig=RIG, out_rig=out)
    with pytest.raises(ValueError, match="distortion \\(or auto\\) must be"):
        photorig.calibrate_camera(boards, board=(9, 6), square_mm=10, rig=RIG, out_rig=out, distortion="fisheye")
    with pytest.raises(ValueError, match="the plane image is number 40"):
        photorig.calibrate_camera(boards, board=(9, 6), square_mm=10, plane_image=40, rig=RIG, out_rig=out)
    # The five photographs about the centre leave the image's corners to extrapolation: a failure, no rig.
    central = photorig.calibrate_camera(boards[:5], board=(9, 6), square_mm=10, rig=RIG, out_rig=out)
    assert central["summary"]["termination"] == "failure" and central["out_rig"] is None
    assert "near the image's corners" in central["summary"]["message"]
    assert not (tmp_path / "never.yaml").exists()
    # A fixed model is fitted alone.
    fixed = photorig.calibrate_camera(boards, board=(9, 6), square_mm=10, rig=RIG, out_rig=str(tmp_path / "k1.yaml"),
                                      distortion="k1")
    assert fixed["distortion_model"] == "k1" and [c["model"] for c in fixed["summary"]["candidates"]] == ["k1"]
