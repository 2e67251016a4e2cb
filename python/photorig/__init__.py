"""photorig in Python: open runs as NumPy arrays and run the solvers in-process.

See docs/python.md for a tour.
"""

from ._photorig import Run, open_run, run_recipe, solve_ps, solve_tomography
from .client import Daemon, DaemonError

__all__ = ["Daemon", "DaemonError", "Run", "open_run", "run_recipe", "solve_ps", "solve_tomography"]
