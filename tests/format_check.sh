#!/usr/bin/env bash
# Checks that every C and C++ file git tracks is formatted as .clang-format says (clang-format, Debian's
# clang-format package). Prints each file that is not, with the command that formats it; exit 1 then.
# Usage: tests/format_check.sh SOURCE_DIR
set -euo pipefail
src="${1:?usage: format_check.sh SOURCE_DIR}"
cd "$src"
if ! command -v clang-format > /dev/null; then
  echo "format_check: clang-format is not installed (deploy/install-deps.sh installs it)" >&2
  exit 1
fi
if ! git rev-parse --is-inside-work-tree > /dev/null 2>&1; then
  echo "format_check: $src is not a git checkout: nothing to check" >&2
  exit 77
fi
bad=0
while IFS= read -r -d '' f; do
  [ -f "$f" ] || continue
  if ! clang-format --dry-run --Werror "$f" > /dev/null 2>&1; then
    echo "not formatted: $f (clang-format -i $f)"
    bad=$((bad + 1))
  fi
done < <(git ls-files -z -- '*.cpp' '*.hpp' '*.h' '*.cc' '*.c')
if [ "$bad" -gt 0 ]; then
  echo "format_check: $bad file(s) differ from .clang-format"
  exit 1
fi
echo "format_check: every tracked C/C++ file is formatted"
