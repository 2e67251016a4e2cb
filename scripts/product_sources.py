"""The product code's C++ files, for the tree checks (check-include-structure.py,
check-typed-names.py): the headers and sources git tracks under solvers/,
daemon/, rigconfig/, sim/, drivers/ and python/ of the tree given as the first argument
(default: this script's tree), which becomes the working directory."""
import os
import subprocess
import sys

PRODUCT_FOLDERS = ("solvers", "daemon", "rigconfig", "sim", "drivers", "python")


def product_sources():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    os.chdir(root)
    patterns = [f"{folder}/*.{ext}" for folder in PRODUCT_FOLDERS for ext in ("h", "cpp")]
    return subprocess.check_output(["git", "ls-files", "--", *patterns], text=True).split()
