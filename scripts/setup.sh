#!/usr/bin/env bash
# One command from a fresh Debian 12 machine (nothing but bash and apt):
#   scripts/setup.sh demo   installs the demo's packages, builds what the demo runs (photorig
#                           and the Python module), captures and solves the demo recipe
#   scripts/setup.sh test   installs every package, builds everything, runs every test
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in
  demo|test) ;;
  *) echo "usage: scripts/setup.sh demo|test" >&2; exit 2 ;;
esac
./scripts/install-deps.sh "$1"
exec make "$1"
