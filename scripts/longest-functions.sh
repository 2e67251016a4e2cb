#!/usr/bin/env bash
# The longest function definitions in the product code (solvers/, daemon/,
# rigconfig/, sim/, drivers/, python/), from Universal Ctags' start and end lines.
# Prints the longest ten; with --max N, exits 1 if any is longer than N lines.
#
#   scripts/longest-functions.sh [--max N] [SOURCE_DIR]
set -euo pipefail
max=0
if [ "${1:-}" = --max ]; then
  max="$2"
  shift 2
fi
cd "${1:-$(dirname "$0")/..}"
command -v ctags >/dev/null 2>&1 || { echo "longest-functions: ctags not found: run scripts/install-deps.sh (universal-ctags)" >&2; exit 2; }
lengths=$(git ls-files 'solvers/*.cpp' 'solvers/*.h' 'daemon/*.cpp' 'daemon/*.h' 'rigconfig/*.cpp' 'rigconfig/*.h' \
                       'sim/*.cpp' 'sim/*.h' 'drivers/*.cpp' 'drivers/*.h' 'python/*.cpp' 'python/*.h' |
  ctags --languages=C++ --kinds-C++=f --fields=+ne -L - -o - |
  awk -F'\t' '{ line = ""; end = ""
                for (i = 4; i <= NF; ++i) { if ($i ~ /^line:/) line = substr($i, 6); if ($i ~ /^end:/) end = substr($i, 5) }
                if (line != "" && end != "") printf "%d %s:%s %s\n", end - line + 1, $2, line, $1 }' |
  sort -rn)
head -n 10 <<<"$lengths"
if [ "$max" -gt 0 ]; then
  over=$(awk -v max="$max" '$1 > max' <<<"$lengths" | wc -l)
  if [ "$over" -gt 0 ]; then
    echo "longest-functions: $over function(s) over $max lines; split them (docs/architecture.md)" >&2
    exit 1
  fi
  echo "every function within $max lines"
fi
