#!/usr/bin/env bash
# Installs every Debian package cdc-slam needs to build, test and run.
# Idempotent: installs only what is missing. Uses sudo when not root; when it
# cannot install, prints the exact command to run and exits non-zero.
set -euo pipefail

PACKAGES=(
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
  # fuzzing (tests/fuzz): clang and its libFuzzer/sanitizer runtimes (libclang_rt.fuzzer)
  clang libclang-rt-dev
  # tests and benchmarks (python3-rosbag writes ROS 1 test bags with an independent implementation)
  libgtest-dev libgmock-dev libbenchmark-dev python3-rosbag
  # network namespaces and fault injection used by tests
  iproute2 iptables util-linux procps tcpdump
  # deployment checks: docker-compose.yml validation (no engine needed), systemd unit verification
  docker-compose systemd
  # run reports: PNG copies of the SVG plots (rsvg-convert)
  librsvg2-bin
)

usage() {
  cat <<USAGE
usage: deploy/install-deps.sh [--list] [--help]
  Installs the Debian 12 packages cdc-slam needs (only the missing ones).
  --list   print the package list and exit
USAGE
}

case "${1:-}" in
  -h|--help) usage; exit 0 ;;
  --list) printf '%s\n' "${PACKAGES[@]}"; exit 0 ;;
  "") ;;
  *) echo "install-deps.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
esac

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
