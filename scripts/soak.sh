#!/usr/bin/env bash
# Long runs of the crash-and-fault test: the real photorigd killed with
# SIGKILL at random points of a capture while the simulated devices drop,
# damage and refuse, then restarted, until the run completes; every frame
# must be on disk exactly once and intact.
#   scripts/soak.sh [KILLS [DARKS [SEED]]]     defaults: 200 kills, 1000 darks (a dark group's most), seed 1
# Needs a built tree (make build). Exits as the test does.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
binary="${PHOTORIG_BUILD_DIR:-$root/build}/bin/test_daemon_crash"
[ -x "$binary" ] || { echo "soak: $binary not found: run make build" >&2; exit 2; }
start=$(date +%s)
status=0
output=$(PHOTORIG_SOAK_KILLS="${1:-200}" PHOTORIG_SOAK_DARKS="${2:-1000}" PHOTORIG_SOAK_SEED="${3:-1}" \
  "$binary" --gtest_filter='Crash.*' 2>&1) || status=$?
grep -E '^soak:|Failure|FAILED' <<<"$output" || true
echo "soak: $(( $(date +%s) - start )) s, exit $status"
exit $status
