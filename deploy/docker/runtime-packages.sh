#!/usr/bin/env bash
# Prints the Debian packages holding the shared libraries that the cdc-* programs under a build folder
# load (ldd, resolved through symbolic links and alternatives to the file dpkg knows), one a line, sorted:
# what a runtime image installs in place of the -dev packages and their tool chain.
set -euo pipefail

usage() {
  cat <<USAGE
usage: deploy/docker/runtime-packages.sh BUILD_DIR
  Lists the Debian packages of every shared library the cdc-* executables under BUILD_DIR link.
USAGE
}

case "${1:-}" in
  -h|--help) usage; exit 0 ;;
  "") usage >&2; exit 2 ;;
esac
[[ $# -eq 1 && -d $1 ]] || { echo "runtime-packages.sh: '$1' is not a folder" >&2; usage >&2; exit 2; }

mapfile -t bins < <(find "$1" -path '*/CMakeFiles' -prune -o -type f -perm -u+x -name 'cdc-*' -print)
[[ ${#bins[@]} -gt 0 ]] || { echo "runtime-packages.sh: no cdc-* programs under $1" >&2; exit 1; }

owner() {
  local f=$1 p
  for f in "$(readlink -f "$1")" "$1"; do
    p=$(dpkg -S "$f" 2>/dev/null | head -1 | cut -d: -f1) && [[ -n $p ]] && { echo "$p"; return; }
    # /lib is a link to /usr/lib on Debian 12; dpkg may know either spelling.
    p=$(dpkg -S "${f#/usr}" 2>/dev/null | head -1 | cut -d: -f1) && [[ -n $p ]] && { echo "$p"; return; }
  done
  echo "runtime-packages.sh: no package holds $1" >&2
  return 1
}

ldd "${bins[@]}" 2>/dev/null | awk '$2 == "=>" && $3 ~ /^\// { print $3 }' | sort -u |
  while read -r lib; do owner "$lib"; done | sort -u
