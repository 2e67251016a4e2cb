"""photorig in Python: open runs as NumPy arrays and run the solvers in-process.

See docs/python.md for a tour.
"""

from ._photorig import (Run, calibrate_camera, calibrate_color, calibrate_leds, calibrate_lights, eval_brdf, fit_brdf,
                        open_run, read_merl, run_recipe, solve_brdf, solve_ps, solve_svbrdf, solve_tomography, write_merl)
from .client import Daemon, DaemonError, DaemonUnreachable

__all__ = [
    "Daemon", "DaemonError", "DaemonUnreachable", "Run", "calibrate_camera", "calibrate_color", "calibrate_leds",
    "calibrate_lights",
    "eval_brdf", "fit_brdf", "open_run", "read_merl", "run_recipe", "solve_brdf", "solve_ps", "solve_svbrdf", "solve_tomography", "write_merl",
]
