#!/usr/bin/env bash
# Lays out what a cdc-slam runtime image holds, under OUT: opt/cdc/bin (the cdc-* programs of a build
# folder, stripped; tests and benchmarks left out), the services' configurations, the Cyclone DDS
# configurations, the radio emulator, the scenarios and swarm configurations, and runtime-packages.txt
# (deploy/docker/runtime-packages.sh). The image's build stage and the compose test's host image use it.
set -euo pipefail

usage() {
  cat <<USAGE
usage: deploy/docker/stage.sh BUILD_DIR OUT
  Copies the runtime files of the repository and of BUILD_DIR into OUT/opt/cdc and writes
  OUT/runtime-packages.txt. OUT is emptied first.
USAGE
}

case "${1:-}" in -h|--help) usage; exit 0 ;; esac
[[ $# -eq 2 ]] || { usage >&2; exit 2; }
build=$1 out=$2
[[ -d $build ]] || { echo "stage.sh: no build folder '$build'" >&2; exit 2; }
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)

rm -rf "$out"
mkdir -p "$out/opt/cdc/bin"
find "$build" -path '*/CMakeFiles' -prune -o -path "$build/tests" -prune -o -type f -perm -u+x -name 'cdc-*' -print |
  while read -r b; do
    install -m 0755 "$b" "$out/opt/cdc/bin/"
    strip --strip-unneeded "$out/opt/cdc/bin/$(basename "$b")"
  done
[[ -x $out/opt/cdc/bin/cdc-frontend ]] || { echo "stage.sh: $build holds no cdc-frontend (not built?)" >&2; exit 1; }
for s in "$repo"/services/*/config; do
  mkdir -p "$out/opt/cdc/services/$(basename "$(dirname "$s")")"
  cp -r "$s" "$out/opt/cdc/services/$(basename "$(dirname "$s")")/"
done
mkdir -p "$out/opt/cdc/deploy/docker" "$out/opt/cdc/deploy/swarms" "$out/opt/cdc/sim"
cp -r "$repo/deploy/cyclonedds" "$out/opt/cdc/deploy/"
cp "$repo/deploy/docker/radio-emulator.sh" "$repo/deploy/docker/after-central.sh" "$out/opt/cdc/deploy/docker/"
cp -r "$repo/deploy/swarms/config" "$out/opt/cdc/deploy/swarms/"
cp -r "$repo/sim/scenarios" "$out/opt/cdc/sim/"
"$repo/deploy/docker/runtime-packages.sh" "$build" > "$out/runtime-packages.txt"
