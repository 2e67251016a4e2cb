#!/usr/bin/env bash
# Internal headers (include/photorig/.../internal/*.h) belong to their module,
# the nearest directory above them with a CMakeLists.txt (drivers/,
# drivers/gpio/, sim/modbus/, ...): only that module's own files and the tests
# may include them. Prints every other includer and exits 1 if there is one.
#
#   scripts/check-internal-headers.sh [SOURCE_DIR]
set -euo pipefail
cd "${1:-$(dirname "$0")/..}"

module_of() {
  local dir
  dir=$(dirname "$1")
  while [ "$dir" != . ] && [ ! -f "$dir/CMakeLists.txt" ]; do dir=$(dirname "$dir"); done
  echo "$dir"
}

status=0
headers=$(find drivers sim solvers daemon -path '*/include/photorig/*/internal/*.h' | sort)
for header in $headers; do
  name=${header#*/include/}
  owner=$(module_of "$header")
  for user in $(grep -rlF --include='*.h' --include='*.cpp' "#include \"$name\"" drivers sim solvers daemon bench || true); do
    if [ "$(module_of "$user")" != "$owner" ]; then
      echo "$user includes $name, internal to $owner/"
      status=1
    fi
  done
done
[ "$status" = 0 ] && echo "internal headers: $(echo "$headers" | wc -w) checked, included only inside their modules"
exit "$status"
