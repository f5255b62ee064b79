#!/usr/bin/env bash
# Installs every Debian package cdc-slam needs to build, test and run.
# Idempotent: installs only what is missing. Uses sudo when not root; when it
# cannot install, prints the exact command to run and exits non-zero.
set -euo pipefail

# What `./cdc build` needs (the image's build stage installs only these: CDC_DEPS=build).
BUILD_PACKAGES=(
  # toolchain
  build-essential cmake ninja-build ccache pkg-config git clang-format
  # middleware and IDL compiler
  cyclonedds-dev cyclonedds-tools
  # algorithms
  libeigen3-dev libpcl-dev libceres-dev liboctomap-dev libnanoflann-dev libsuitesparse-dev
  # configuration, CLI, logging, JSON
  libyaml-cpp-dev libcli11-dev libspdlog-dev nlohmann-json3-dev
  # compact wire encodings (DEFLATE)
  zlib1g-dev
  # recordings: ROS 2 bags (sqlite3, MCAP chunks in zstd/lz4), ROS 1 bag chunks (bz2/lz4), pcap
  libsqlite3-dev libzstd-dev liblz4-dev libbz2-dev libpcap-dev
  # unit tests and benchmarks (built with everything)
  libgtest-dev libgmock-dev libbenchmark-dev
)

# What the tests, the demo and the deployment checks need beyond the build.
TOOL_PACKAGES=(
  # fuzzing (tests/fuzz): clang and its libFuzzer/sanitizer runtimes (libclang_rt.fuzzer)
  clang libclang-rt-dev
  # python3-rosbag writes ROS 1 test bags with an independent implementation
  python3-rosbag
  # network namespaces and fault injection used by tests
  iproute2 iptables util-linux procps tcpdump
  # deployment checks: docker-compose.yml validation (no engine needed), systemd unit verification
  docker-compose systemd
  # the compose swarm run for real (tests/compose): a container engine and the base image's maker
  docker.io debootstrap
  # run reports: PNG copies of the SVG plots (rsvg-convert)
  librsvg2-bin
)

usage() {
  cat <<USAGE
usage: deploy/install-deps.sh [--build] [--list] [--help]
  Installs the Debian 12 packages cdc-slam needs (only the missing ones).
  --build  only what the build needs (also when CDC_DEPS=build, as in the image's build stage)
  --list   print the package list and exit
USAGE
}

set_=${CDC_DEPS:-all}
list=0
for arg in "$@"; do
  case "$arg" in
    -h|--help) usage; exit 0 ;;
    --list) list=1 ;;
    --build) set_=build ;;
    *) echo "install-deps.sh: unknown argument '$arg'" >&2; usage >&2; exit 2 ;;
  esac
done
case "$set_" in
  build) PACKAGES=("${BUILD_PACKAGES[@]}") ;;
  all) PACKAGES=("${BUILD_PACKAGES[@]}" "${TOOL_PACKAGES[@]}") ;;
  *) echo "install-deps.sh: CDC_DEPS must be 'build' or 'all', not '$set_'" >&2; exit 2 ;;
esac
if [ "$list" = 1 ]; then printf '%s\n' "${PACKAGES[@]}"; exit 0; fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${#missing[@]} missing packages: ${missing[*]}"
SUDO=()
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    SUDO=(sudo)
  else
    echo "install-deps: not root and no password-less sudo. Run as root:" >&2
    echo "  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ${missing[*]}" >&2
    exit 1
  fi
fi

export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -qq
"${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "install-deps: done"
