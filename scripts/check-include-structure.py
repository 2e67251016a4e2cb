#!/usr/bin/env python3
"""Include structure of the product code (docs/architecture.md):

- no two modules include each other, a module being a header and the source
  of the same name (foo.h, foo.cpp) in one CMake module of solvers/, daemon/,
  rigconfig/, sim/, drivers/ (KNOWN_PAIRS, below, lists none);
- no second names: a daemon header never brings another layer's type into
  the daemon's namespace (`using config::X;`, `using solvers::...::X;`), so
  each type keeps one name;
- the daemon's public headers (include/photorig/daemon/, outside internal/)
  include no simulator header: the simulator is a private dependency.

Prints each breach and exits 1 if there is one.

    scripts/check-include-structure.py [SOURCE_DIR]
"""
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from product_sources import product_sources  # noqa: E402

files = product_sources()
include = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def module(path):
    """A header and its source share a module: photorig/daemon/capture/plan.h ~ .../src/capture/plan.cpp."""
    base = os.path.splitext(os.path.basename(path))[0]
    return base


# Header include paths ("photorig/...") to the files that hold them.
by_include = {}
for f in files:
    if "/include/" in f and f.endswith(".h"):
        by_include[f.split("/include/", 1)[1]] = f

edges = {}  # file module key -> set of module keys it includes
def owner(path):
    """The nearest directory above the file with a CMakeLists.txt (solvers/ps, daemon, drivers/gpio)."""
    d = os.path.dirname(path)
    while d and not os.path.exists(os.path.join(d, "CMakeLists.txt")):
        d = os.path.dirname(d)
    return d


def key(path):
    # A header and the source of its name in one CMake module: daemon:plan for plan.h and plan.cpp.
    return (owner(path), module(path))

breaches = []
for f in files:
    text = open(f, encoding="utf-8", errors="replace").read()
    for target in include.findall(text):
        header = by_include.get(target) or (os.path.normpath(os.path.join(os.path.dirname(f), target))
                                            if os.path.exists(os.path.join(os.path.dirname(f), target)) else None)
        if header is None or key(header) == key(f):
            continue
        edges.setdefault(key(f), set()).add(key(header))
    if f.startswith("daemon/include/") and "/internal/" not in f:
        for target in include.findall(text):
            if target.startswith("photorig/sim/"):
                breaches.append(f"{f}: a public daemon header includes the simulator's {target}")
    if f.startswith("daemon/") and f.endswith(".h"):
        for line in text.splitlines():
            if re.match(r"\s*using (photorig::)?(config|solvers)::[\w:]+;", line):
                breaches.append(f"{f}: gives another layer's type a second name: {line.strip()}")

# Pairs allowed to include each other, as (CMake module, module, module):
# none. Types two modules share have a header of their own instead. An entry
# whose pair is gone from the code fails, so the list cannot go stale.
KNOWN_PAIRS = set()
found = set()
for a, targets in edges.items():
    for b in targets:
        if a < b and a in edges.get(b, set()):
            pair = (a[0], a[1], b[1]) if a[0] == b[0] else None
            found.add(pair)
            if pair not in KNOWN_PAIRS:
                breaches.append(f"{a[0]}: {a[1]} and {b[0]}: {b[1]} include each other")
for pair in sorted(KNOWN_PAIRS - found):
    breaches.append(f"{pair[0]}: {pair[1]} and {pair[2]} no longer include each other: take them off KNOWN_PAIRS")

for line in sorted(breaches):
    print(line)
if breaches:
    sys.exit(1)
print(f"include structure: {len(files)} files, no module pair including each other, no second names, "
      f"no simulator header in the daemon's public headers")
