#!/usr/bin/python3
"""Checks a NeXus file `photorig export nexus` wrote against its run.

usage: check_nexus.py FILE RUN

nxvalidate is not packaged in Debian 12, so the structure is checked here:
every group has its NX_class; each class written has the fields and
attributes NXDL asks of it (NXentry, NXinstrument, NXdetector, NXsample,
NXdata with `signal` and `axes`, NXprocess with program, version and date,
NXnote with type and data); the frames read back equal to the run's PNGs,
chunked one frame per chunk and compressed; each NXprocess holds its results
folder's report and outputs unchanged. Then the NeXus C API's own reader
(nxdir, nxsummary from nexus-tools) must list the file. Prints each problem
and exits 1 if there is any.
"""
import json
import pathlib
import re
import subprocess
import sys

import cv2
import h5py
import numpy as np

problems = []


def need(condition, what):
    if not condition:
        problems.append(what)
    return condition


def text(value):
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    return value.decode() if isinstance(value, bytes) else str(value)


def check_group(f, path, nx_class, fields=(), attributes=()):
    if not need(path in f, f"{path} is missing"):
        return False
    group = f[path]
    need(text(group.attrs.get("NX_class", "")) == nx_class, f"{path}: NX_class is not {nx_class}")
    for field in fields:
        need(field in group, f"{path} ({nx_class}) has no {field}")
    for attribute in attributes:
        need(attribute in group.attrs, f"{path} ({nx_class}) has no attribute {attribute}")
    return True


def check_nxdata(f, path):
    if not check_group(f, path, "NXdata", attributes=("signal", "axes")):
        return
    group = f[path]
    signal = text(group.attrs["signal"])
    if not need(signal in group, f"{path}: its signal {signal} is missing"):
        return
    axes = [text(a) for a in np.atleast_1d(group.attrs["axes"])]
    need(len(axes) == group[signal].ndim, f"{path}: {len(axes)} axes for a {group[signal].ndim}-D signal")
    for dim, axis in enumerate(axes):
        if axis != ".":
            ok = need(axis in group, f"{path}: axis {axis} is missing")
            if ok and f"{axis}_indices" in group.attrs:
                dim = int(group.attrs[f"{axis}_indices"])
            need(not ok or group[axis].shape[0] == group[signal].shape[dim],
                 f"{path}: axis {axis} does not match the signal's dimension {dim}")


def check_note(f, path, expected=None):
    if check_group(f, path, "NXnote", fields=("type", "data")) and expected is not None:
        need(text(f[path + "/data"][()]) == expected, f"{path}/data differs from the file it copies")


def check_process(f, path, folder):
    if not check_group(f, path, "NXprocess", fields=("program", "version", "date", "sequence_index")):
        return
    need(re.match(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d", text(f[path + "/date"][()])), f"{path}/date is not ISO 8601")
    need(f[path + "/sequence_index"].shape == () and f[path + "/sequence_index"][()] >= 1,
         f"{path}/sequence_index is not a positive integer")
    check_note(f, path + "/report", (folder / "report.json").read_text())
    report = json.loads((folder / "report.json").read_text())
    if "provenance" in report:
        need(text(f[path + "/version"][()]) == report["provenance"]["version"], f"{path}/version is not the report's")
        check_note(f, path + "/options")
        need(json.loads(text(f[path + "/options/data"][()])) == report["provenance"]["options"],
             f"{path}/options are not the report's")
        check_note(f, path + "/input_checksums")
    for name in ("normals", "albedo", "confidence", "depth"):
        tiff = folder / f"{name}.tiff"
        if not tiff.exists():
            continue
        check_nxdata(f, f"{path}/{name}")
        image = cv2.imread(str(tiff), cv2.IMREAD_UNCHANGED)
        if image.ndim == 3:
            image = image[:, :, ::-1]  # OpenCV's B, G, R -> the file's x, y, z
        need(np.array_equal(f[f"{path}/{name}/data"][()], image, equal_nan=True), f"{path}/{name} differs from {tiff}")
    if (folder / "volume.nrrd").exists():
        check_nxdata(f, f"{path}/volume")
        need(np.array_equal(f[f"{path}/volume/data"][()], read_nrrd(folder / "volume.nrrd")),
             f"{path}/volume differs from volume.nrrd")
    if "chosen" in report:
        check_group(f, f"{path}/parameters", "NXparameters", fields=("model", "diffuse", "specular"))
        chosen = next(c for c in report["candidates"] if c["model"] == report["chosen"])
        need(text(f[f"{path}/parameters/model"][()]) == chosen["model"], f"{path}/parameters/model is not the choice")
        need(list(f[f"{path}/parameters/diffuse"][()]) == chosen["diffuse"], f"{path}/parameters/diffuse differs")
        need(f[f"{path}/parameters/shape"][()] == chosen["shape"], f"{path}/parameters/shape differs")
        check_note(f, f"{path}/samples", (folder / "samples.csv").read_text())


def read_nrrd(path):
    raw = path.read_bytes()
    header, data = raw.split(b"\n\n", 1)
    fields = dict(line.split(": ", 1) for line in header.decode().splitlines()[1:] if ": " in line)
    nx, ny, nz = (int(n) for n in fields["sizes"].split())
    dtype = "<f4" if fields.get("endian", "little") == "little" else ">f4"
    return np.frombuffer(data, dtype=dtype).reshape(nz, ny, nx)


def check_frames(f, run, manifest):
    check_nxdata(f, "/entry/data")
    data = f["/entry/data/data"]
    frames = manifest["frames"]
    need(data.shape[0] == len(frames), f"{len(frames)} frames in the run, {data.shape[0]} in the file")
    need(data.chunks is not None and data.chunks[0] == 1 and data.chunks[1:] == data.shape[1:],
         "the frame stack is not chunked one frame per chunk")
    need(data.compression == "gzip", "the frame stack is not deflate-compressed")
    keys = f["/entry/data/image_key"][()]
    for i, frame in enumerate(frames):
        png = cv2.imread(str(run / frame["file"]), cv2.IMREAD_UNCHANGED)
        if png.ndim == 3:
            png = png[:, :, ::-1]  # OpenCV's B, G, R -> the run's R, G, B
        need(png.dtype == np.uint16 and np.array_equal(data[i], png), f"frame {i} differs from {frame['file']}")
        need((keys[i] == 2) == (frame["kind"] == "dark"), f"frame {i}: image_key {keys[i]} for a {frame['kind']} frame")
    need(list(f["/entry/data/crc32"][()]) == [fr["crc32"] for fr in frames], "the frames' checksums differ")


def check_independent_reader(path, manifest):
    listing = subprocess.run(["nxdir", str(path), "-p", "/entry/data/*"], capture_output=True, text=True)
    need(listing.returncode == 0, f"nxdir failed ({listing.returncode}): {listing.stderr}")
    shape = f"/entry/data/data[{len(manifest['frames'])},{manifest['camera']['height']},{manifest['camera']['width']}"
    need(shape in listing.stdout, f"nxdir does not list {shape}: {listing.stdout}")
    summary = subprocess.run(["nxsummary", str(path)], capture_output=True, text=True)
    need(summary.returncode == 0 and manifest["run_id"] in summary.stdout, f"nxsummary: {summary.stdout}{summary.stderr}")


def main(path, run):
    path, run = pathlib.Path(path), pathlib.Path(run)
    manifest = json.loads((run / "manifest.json").read_text())
    with h5py.File(path, "r") as f:
        for attribute in ("file_name", "file_time", "creator", "HDF5_Version", "default"):
            need(attribute in f.attrs, f"the file has no attribute {attribute}")
        need(text(f.attrs.get("file_name", "")) == path.name, "file_name is not the file's name")
        groups = []
        f.visititems(lambda name, item: groups.append(name) if isinstance(item, h5py.Group) else None)
        need(len(groups) > 5, f"only {len(groups)} groups")
        for name in groups:
            need("NX_class" in f[name].attrs, f"/{name} has no NX_class")
        check_group(f, "/entry", "NXentry", fields=("title", "start_time", "end_time", "data"), attributes=("default",))
        need(text(f["/entry"].attrs["default"]) in f["/entry"], "/entry's default names no group")
        check_group(f, "/entry/instrument", "NXinstrument", fields=("name", "camera"))
        check_group(f, "/entry/instrument/camera", "NXdetector", fields=("data", "x_pixel_size", "image_key"))
        check_note(f, "/entry/instrument/rig", pathlib.Path(manifest["rig"]["path"]).read_text())
        check_note(f, "/entry/manifest", (run / "manifest.json").read_text())
        check_group(f, "/entry/sample", "NXsample", fields=("name",))
        if manifest["lights"]:
            check_group(f, "/entry/instrument/lights", "NXcollection", fields=("direction", "intensity"))
            need(np.allclose(f["/entry/instrument/lights/direction"][()], [l["direction"] for l in manifest["lights"]],
                             rtol=0, atol=0), "the lights' directions differ from the manifest's")
        if any("pose" in frame for frame in manifest["frames"]):
            check_group(f, "/entry/instrument/sample_rotation", "NXpositioner", fields=("name", "value"))
            check_group(f, "/entry/instrument/light_arm", "NXpositioner", fields=("name", "value"))
            need("rotation_angle" in f["/entry/sample"], "/entry/sample has no rotation_angle")
        check_frames(f, run, manifest)
        for name in ("ps", "brdf", "tomography"):
            folder = run / "results" / name
            if need((folder / "report.json").exists() == (f"/entry/{name}" in f), f"results/{name} and /entry/{name}"):
                if folder.exists():
                    check_process(f, f"/entry/{name}", folder)
    check_independent_reader(path, manifest)
    for problem in problems:
        print(problem)
    return 1 if problems else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
