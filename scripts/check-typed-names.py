#!/usr/bin/env python3
"""A solve's method, a frame's kind and the other choices a request makes are
enums everywhere past the parsers (docs/architecture.md, "Names at the edges"):
YAML and the command line read them through the solvers' name tables
(photorig/solvers/core/names.h), and code compares enums, never text.

Prints each comparison of such a field with a string literal in the product
code (solvers/, daemon/, rigconfig/, sim/, drivers/) and exits 1 if there is one.

    scripts/check-typed-names.py [SOURCE_DIR]
"""
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from product_sources import product_sources  # noqa: E402

files = product_sources()

# Fields that hold a choice of a request or a record.
FIELDS = ("method", "integrator", "derivative", "projector", "loss", "demosaic", "calibration", "sphere_source",
          "group", "kind", "model", "executor", "beam")
field = r"\w*(?:\.|->)(?:" + "|".join(FIELDS) + r")\b"
literal = r'"[^"\n]*"'
compare = re.compile(rf"{field}\s*[!=]=\s*{literal}|{literal}\s*[!=]=\s*[\w.>-]*{field}")
# HTTP verbs are the protocol's own text, not a choice of ours.
ALLOWED = re.compile(r"^req\.method\b")

breaches = 0
for path in files:
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            code = line.split("//", 1)[0]
            for match in compare.finditer(code):
                if ALLOWED.search(match.group(0)):
                    continue
                print(f"{path}:{number}: compares a choice with text: {match.group(0).strip()}")
                breaches += 1
if breaches:
    print(f"{breaches} comparison(s): parse the text once through the enum's name table, then compare enums")
sys.exit(1 if breaches else 0)
