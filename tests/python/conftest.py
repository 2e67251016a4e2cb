"""Fixtures: the CLI and the runs it captures, which the module is compared with."""

import json
import math
import os
import subprocess
from pathlib import Path

import pytest

SOURCE_DIR = Path(os.environ.get("PHOTORIG_SOURCE_DIR", Path(__file__).resolve().parents[2]))
BIN_DIR = Path(os.environ.get("PHOTORIG_BIN_DIR", SOURCE_DIR / "build" / "bin"))


def as_written(value):
    """A summary as report.json holds it: JSON writes NaN (a deviation not estimated) as null."""
    if isinstance(value, dict):
        return {key: as_written(item) for key, item in value.items()}
    if isinstance(value, list):
        return [as_written(item) for item in value]
    return None if isinstance(value, float) and math.isnan(value) else value


# Wall-clock figures, which no two solves share: each summary's timings_ms and the colour reports' own.
TIMINGS = {"timings_ms", "total_ms", "fit_ms", "loo_ms"}


def without_timings(value):
    """A summary less its wall-clock figures, at every depth."""
    if isinstance(value, dict):
        return {key: without_timings(item) for key, item in value.items() if key not in TIMINGS}
    if isinstance(value, list):
        return [without_timings(item) for item in value]
    return value


def photorig(*args):
    """Runs the CLI; fails the test with its output when it fails."""
    done = subprocess.run([str(BIN_DIR / "photorig"), *map(str, args)], capture_output=True, text=True)
    assert done.returncode == 0, f"photorig {' '.join(map(str, args))}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def photorig_json(*args):
    """Runs the CLI with --json: its result's fields, without the command's own (`command`, `ok`, `exit_code`)."""
    printed = json.loads(photorig(*args, "--json"))
    return {key: value for key, value in printed.items() if key not in ["command", "ok", "exit_code"]}


def capture(recipe, folder):
    """The recipe (in config/recipes) captured by the CLI into folder/run, not solved."""
    run = folder / "run"
    photorig("run", SOURCE_DIR / "config/recipes" / recipe, "--no-solve", "--out", run)
    return run


@pytest.fixture(scope="session")
def cli():
    return photorig


@pytest.fixture(scope="session")
def demo_run(tmp_path_factory):
    """The demo's capture (`make demo`): the sphere on the simulated dome, solved by the CLI."""
    run = tmp_path_factory.mktemp("runs") / "demo"
    photorig("run", SOURCE_DIR / "config/recipes/ps-sphere.yaml", "--out", run)
    return run
