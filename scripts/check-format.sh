#!/usr/bin/env bash
# Fails when a C++ file differs from what clang-format (.clang-format) makes of it, listing each such file.
# Usage: check-format.sh [FILE...]  (default: every tracked .cpp and .h file; a clone without git: every
# such file under the source folders)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -gt 0 ]; then
  files=("$@")
elif git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  mapfile -t files < <(git ls-files -- '*.cpp' '*.h')
else
  mapfile -t files < <(find base bake bench bounds cli cluster data examples export fuzz io query render runtime stats \
    tests view \( -name '*.cpp' -o -name '*.h' \) 2>/dev/null | sort)
fi
bad=0
for f in "${files[@]}"; do
  [ -f "$f" ] || continue
  if ! clang-format --dry-run --Werror "$f" >/dev/null 2>&1; then
    echo "not formatted: $f (clang-format -i $f)"
    bad=$((bad + 1))
  fi
done
echo "check-format: ${#files[@]} files, $bad not formatted"
[ "$bad" -eq 0 ]
