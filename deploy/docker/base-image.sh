#!/usr/bin/env bash
# Makes sure the engine has a debian:12 image: present already, pulled, or, where no image registry is
# reachable, made from Debian's package registry with debootstrap (minbase) and `docker import`.
set -euo pipefail

IMAGE=debian:12
MIRROR=${CDC_DEBIAN_MIRROR:-http://deb.debian.org/debian}

usage() {
  cat <<USAGE
usage: deploy/docker/base-image.sh [--no-pull] [--mirror URL]
  Leaves the image $IMAGE in the engine DOCKER_HOST names: kept when present, else pulled, else made with
  'debootstrap --variant=minbase bookworm' from the mirror (default $MIRROR) and 'docker import'.
  --no-pull   skip the pull attempt (no image registry reachable)
Needs root and debootstrap for the last case.
USAGE
}

pull=1
while [[ $# -gt 0 ]]; do
  case $1 in
    --no-pull) pull=0; shift ;;
    --mirror) MIRROR=${2:?--mirror needs a URL}; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "base-image.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done

if docker image inspect "$IMAGE" >/dev/null 2>&1; then
  echo "base-image: $IMAGE present"
  exit 0
fi
if [[ $pull == 1 ]] && timeout 60 docker pull -q "$IMAGE" >/dev/null 2>&1; then
  echo "base-image: $IMAGE pulled"
  exit 0
fi
command -v debootstrap >/dev/null || { echo "base-image: no $IMAGE, no registry and no debootstrap" >&2; exit 1; }
root=$(mktemp -d /var/tmp/cdc-debootstrap.XXXXXX)
trap 'rm -rf "$root"' EXIT
echo "base-image: no image registry; debootstrap --variant=minbase bookworm from $MIRROR"
debootstrap --variant=minbase bookworm "$root" "$MIRROR" > "$root.log" 2>&1 ||
  { tail -20 "$root.log" >&2; rm -f "$root.log"; exit 1; }
rm -f "$root.log"
rm -rf "$root"/var/cache/apt/archives/*.deb "$root"/var/lib/apt/lists/*
tar -C "$root" --numeric-owner -c . | docker import --change 'CMD ["bash"]' - "$IMAGE" >/dev/null
echo "base-image: $IMAGE made ($(docker image inspect -f '{{.Size}}' "$IMAGE") bytes)"
