#!/usr/bin/env python3
"""The shape of the solvers' public API (docs/architecture.md, "The solver contract"):

- every public header of a solver family lives under
  solvers/<family>/include/photorig/solvers/<family>/ and declares its API in
  namespace photorig::solvers::<family>: every photorig namespace it opens is
  that one or ::internal or ::testing inside it (Eigen's and std's trait
  specialisations are not photorig's and are not checked);
- every `struct ...Options` of those headers declares
  `bool IsValid(std::string* why) const`;
- no `throw` in solvers/*/src or solvers/*/include, except in the file
  readers of THROWING_READERS, whose headers document it.

Prints each breach and exits 1 if there is one.

    scripts/check-solver-api-shape.py [SOURCE_DIR]
"""
import os
import re
import sys

# File readers that report a malformed file by exception, as their headers
# say; an entry whose file no longer throws fails, so the list cannot go stale.
THROWING_READERS = {
    "solvers/color/src/model_io.cpp": "colour model files (model_io.h: ParseModel, ModelFromJson)",
    "solvers/lighting/src/light_files.cpp": "light direction and intensity files (light_files.h)",
}
SOURCE_EXTENSIONS = (".h", ".hpp", ".cpp", ".cc", ".cpp.in")

root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
os.chdir(root)

# Comments and literals out, newlines kept (so line numbers hold): what is left is code.
CODE_NOISE = re.compile(r'//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'', re.S)


def code_of(text):
    return CODE_NOISE.sub(lambda m: "\n" * m.group(0).count("\n") if m.group(0).startswith("/*") else
                          (" " if m.group(0).startswith("//") else '""'), text)


def line_of(text, index):
    return text.count("\n", 0, index) + 1


def namespaces_opened(code):
    """(fully qualified name, line) of every `namespace X {`, nested ones joined with their outer ones."""
    opened, stack = [], []
    for m in re.finditer(r"\bnamespace\s+([\w:]*)\s*\{|[{}]", code):
        if m.group(0) == "}":
            if stack:
                stack.pop()
        elif m.group(0) == "{":
            stack.append(None)
        else:
            name = "::".join([s for s in stack if s] + [m.group(1)]) if m.group(1) else None
            stack.append(name)
            if name:
                opened.append((name, line_of(code, m.start())))
    return opened


def body_at(code, open_brace):
    """The text between the brace at open_brace and its match."""
    depth = 0
    for i in range(open_brace, len(code)):
        depth += {"{": 1, "}": -1}.get(code[i], 0)
        if depth == 0:
            return code[open_brace + 1:i]
    return code[open_brace + 1:]


def top_level(body):
    """`body` with every nested brace block emptied: only the struct's own members."""
    out, depth = [], 0
    for c in body:
        if c == "}":
            depth -= 1
        if depth == 0:
            out.append(c)
        if c == "{":
            depth += 1
    return "".join(out)


def check_header(path, family, code, breaches):
    expected = f"solvers/{family}/include/photorig/solvers/{family}/"
    if not path.startswith(expected):
        breaches.append(f"{path}: a public header of solvers/{family} outside {expected}")
    own = f"photorig::solvers::{family}"
    allowed = (own, own + "::internal", own + "::testing")
    opened = namespaces_opened(code)
    if not any(name in allowed for name, _ in opened):
        breaches.append(f"{path}: declares nothing in namespace {own}")
    for name, line in opened:
        if name.split("::")[0] == "photorig" and name not in allowed:
            breaches.append(f"{path}:{line}: namespace {name}, not {own} (or ::internal, ::testing inside it)")
    for m in re.finditer(r"\bstruct\s+(\w*Options)\b[^{;]*\{", code):
        members = top_level(body_at(code, m.end() - 1))
        if not re.search(r"\bbool\s+IsValid\s*\(\s*std::string\s*\*\s*\w*\s*\)\s*const\b", members):
            breaches.append(f"{path}:{line_of(code, m.start())}: {m.group(1)} declares no "
                            f"bool IsValid(std::string* why) const")


breaches = []
throwing = set()
for family in sorted(os.listdir("solvers")):
    for part in ("include", "src"):
        top = os.path.join("solvers", family, part)
        for directory, _, names in sorted(os.walk(top)):
            for name in sorted(names):
                if not name.endswith(SOURCE_EXTENSIONS):
                    continue
                path = os.path.join(directory, name).replace(os.sep, "/")
                code = code_of(open(path, encoding="utf-8", errors="replace").read())
                if part == "include" and name.endswith((".h", ".hpp")):
                    check_header(path, family, code, breaches)
                for m in re.finditer(r"\bthrow\b", code):
                    if path in THROWING_READERS:
                        throwing.add(path)
                    else:
                        breaches.append(f"{path}:{line_of(code, m.start())}: throw in solver code (end with a "
                                        f"Summary, a bool or an optional and the reason instead)")
for path in sorted(set(THROWING_READERS) - throwing):
    breaches.append(f"{path}: no longer throws: take it off THROWING_READERS")

for line in breaches:
    print(line)
if breaches:
    sys.exit(1)
print(f"solver API shape: public headers in photorig/solvers/<family>/ and its namespace, every Options with "
      f"IsValid, no throw outside the {len(THROWING_READERS)} file readers listed")
