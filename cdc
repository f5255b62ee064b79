#!/usr/bin/env bash
# cdc-slam entry script: every subcommand does its own set-up on a fresh Debian 12 machine.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
cd "$ROOT"

usage() {
  cat <<'USAGE'
usage: ./cdc <command> [options]

commands:
  demo              build (release) and run the three-robot KITTI-05 demo: three simulated robots, the
                    central node, the emulated radio; results and report in results/kitti05_demo-<time>/
  test              install dependencies, configure, build and run the whole test suite
                    (inside a private network namespace holding only lo)
  build             install dependencies, configure and build
  deps              install the Debian packages (deploy/install-deps.sh)
  help              this text

options:
  --preset NAME     CMake preset: dev, release, asan, ci (default: ci for test, dev for build)
  -L LABEL          test: run only tests with this ctest label (unit, slow, integration, dds, data, format, fuzz,
                    compose)
  -R REGEX          test: run only tests whose name matches
  --out DIR         demo: results folder
  --network MODE    demo: auto (default), netns or loopback
  --max-scans N     demo: sweeps per robot (a shorter run)

environment:
  CDC_DATA_DIR      reference data folder (default ../shared/data); tests needing it skip without it
  CDC_NO_NETNS=1    test: do not enter a private network namespace
  CDC_NO_DOCKER=1   test: no container engine set-up (the compose test skips)
  CDC_DOCKER_DIR    test: the private engine's folder (default /var/tmp/cdc-docker; its image cache stays)
USAGE
}

if [ -t 1 ]; then
  log() { printf '\033[1mcdc:\033[0m %s\n' "$*"; }
else
  log() { printf 'cdc: %s\n' "$*"; }
fi

ensure_deps() {
  "$ROOT/deploy/install-deps.sh"
}

configure_and_build() {
  local preset=$1
  if [ -n "${CDC_DATA_DIR:-}" ]; then
    cmake --preset "$preset" -DCDC_DATA_DIR="$CDC_DATA_DIR" >/dev/null
  else
    cmake --preset "$preset" >/dev/null
  fi
  log "building (preset $preset)"
  cmake --build --preset "$preset"
}

# Runs "$@" in a private network namespace holding only lo, so that no misconfiguration can
# reach a real network. Falls back, with a notice, where the machine forbids namespaces.
run_isolated() {
  if [ "${CDC_NO_NETNS:-0}" = 1 ]; then
    log "notice: CDC_NO_NETNS=1, tests run on the host network (loopback DDS configuration still applies)"
    "$@"
    return
  fi
  local inner='ip link set lo up && exec "$@"'
  if [ "$(id -u)" -eq 0 ] && unshare --net true 2>/dev/null; then
    log "tests run in a private network namespace (unshare --net, only lo)"
    unshare --net -- bash -c "$inner" bash "$@"
  elif unshare --user --map-root-user --net true 2>/dev/null; then
    log "tests run in a private user+network namespace (only lo)"
    unshare --user --map-root-user --net -- bash -c "$inner" bash "$@"
  else
    log "notice: this machine forbids network namespaces; tests run on the host network (loopback DDS configuration still applies)"
    "$@"
  fi
}

# The compose test's container engine (tests/compose), set up on the host network before the tests enter
# their namespace: the only step that reaches Debian's package registry (the base image and the runtime
# libraries layer). Starts a private dockerd (deploy/docker/engine.sh) unless one runs, and stops only
# what it started. Where no engine can run, the compose test says so and skips.
ENGINE_STARTED=0
compose_setup() {
  local build_dir=$1 engine="$ROOT/deploy/docker/engine.sh"
  if [ "${CDC_NO_DOCKER:-0}" = 1 ] || [ "$(id -u)" -ne 0 ] || ! command -v dockerd >/dev/null; then
    log "notice: no container engine here (not root, no dockerd or CDC_NO_DOCKER=1): the compose test skips"
    return
  fi
  if ! "$engine" status; then
    "$engine" start || { log "notice: dockerd did not start: the compose test fails"; return; }
    ENGINE_STARTED=1
  fi
  local stage
  stage=$(mktemp -d)
  if DOCKER_HOST=$("$engine" host) "$ROOT/deploy/docker/base-image.sh" &&
    "$ROOT/deploy/docker/stage.sh" "$build_dir" "$stage/ctx" &&
    DOCKER_HOST=$("$engine" host) docker build -q -f deploy/docker/Dockerfile.host --target libs \
      -t cdc-slam-libs:host "$stage/ctx" >/dev/null; then
    log "container engine ready, runtime libraries image cdc-slam-libs:host built"
  else
    log "notice: the compose test's images could not be made: it fails"
  fi
  rm -rf "$stage"
}

compose_teardown() {
  if [ "$ENGINE_STARTED" = 1 ]; then "$ROOT/deploy/docker/engine.sh" stop; ENGINE_STARTED=0; fi
}

cmd=${1:-help}
shift || true
preset=""
ctest_args=()
launch_args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --preset) preset=${2:?--preset needs a name}; shift 2 ;;
    -L|-R) ctest_args+=("$1" "${2:?$1 needs a value}"); shift 2 ;;
    -h|--help) usage; exit 0 ;;
    --out|--network|--max-scans) launch_args+=("$1" "${2:?$1 needs a value}"); shift 2 ;;
    *) echo "cdc: unknown option '$1'" >&2; usage >&2; exit 2 ;;
  esac
done

case "$cmd" in
  help|-h|--help) usage ;;
  deps) ensure_deps ;;
  build)
    ensure_deps
    configure_and_build "${preset:-dev}"
    ;;
  test)
    start=$(date +%s)
    ensure_deps
    preset=${preset:-ci}
    configure_and_build "$preset"
    trap compose_teardown EXIT
    compose_setup "build/$preset"
    log "running tests"
    run_isolated ctest --preset "$preset" -j "$(nproc)" "${ctest_args[@]}"
    log "test run finished in $(( $(date +%s) - start )) s"
    ;;
  demo)
    start=$(date +%s)
    ensure_deps
    configure_and_build release
    built=$(date +%s)
    log "running the three-robot KITTI-05 demo (deploy/swarms/kitti05_demo.yaml); Ctrl-C stops it cleanly"
    status=0
    build/release/deploy/launch/cdc-launch deploy/swarms/kitti05_demo.yaml --bin-dir build/release "${launch_args[@]}" || status=$?
    log "demo finished in $(( $(date +%s) - built )) s after the build ($(( $(date +%s) - start )) s in all)"
    exit "$status"
    ;;
  *) echo "cdc: unknown command '$cmd'" >&2; usage >&2; exit 2 ;;
esac
