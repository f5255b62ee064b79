#!/usr/bin/env bash
# The docker-compose swarm run for real: the top-level docker-compose.yml (three robots) on the first 60 s of
# the KITTI-05 split, with an image of this build's programs (deploy/docker/Dockerfile.host over the runtime
# libraries layer that `./cdc test` builds before entering its network namespace). Asserts from the results
# volume: every robot's trajectories and the central's graph written; every robot but robot 0 (which carries
# the central) switched to DISTRIBUTED on a liveliness lapse, because its radio emulator cut its links, and
# back after the final rendezvous; every robot's ATE under 0.5 % of its length; and `docker-compose down`
# leaves no container, network, bridge or iptables rule behind.
# The run's mode timeline and ATE per robot stay in BUILD_DIR/compose-summary.txt.
# Usage: compose_test.sh REPO BUILD_DIR (CDC_DATA_DIR: KITTI ground truth; CDC_DOCKER_DIR: the engine's folder)
set -euo pipefail
repo=$(cd "$1" && pwd) build=$(cd "$2" && pwd)
engine="$repo/deploy/docker/engine.sh"
project=cdccomposetest
work="$build/compose-test"
export CDC_IMAGE=cdc-slam:compose-test CDC_DATASET="$work/dataset" CDC_RESULTS="$work/results"
fail() { echo "FAIL: $*" >&2; exit 1; }
skip() { echo "SKIP: $*" >&2; exit 77; }
log() { echo "compose_test: $(date -u +%T) $*"; }
dc() { docker-compose -p "$project" -f "$repo/docker-compose.yml" "$@"; }

preflight() {
  [[ ${CDC_NO_DOCKER:-0} != 1 ]] || skip "CDC_NO_DOCKER=1: no container engine set up"
  [[ $(id -u) -eq 0 ]] || skip "needs root to run a Docker engine"
  command -v dockerd > /dev/null && command -v docker-compose > /dev/null ||
    skip "no dockerd or docker-compose (deploy/install-deps.sh installs docker.io and docker-compose)"
  [[ -d /sys/fs/cgroup ]] && [[ -n $(ls /sys/fs/cgroup) ]] || skip "no cgroups: no container can run here"
  [[ -f ${CDC_DATA_DIR:-}/kitti/poses/05.txt ]] || skip "no KITTI ground truth in CDC_DATA_DIR (${CDC_DATA_DIR:-unset})"
  "$engine" status ||
    fail "no engine answers on $("$engine" host): './cdc test' starts it before the tests (deploy/docker/engine.sh start)"
  export DOCKER_HOST
  DOCKER_HOST=$("$engine" host)
  docker image inspect cdc-slam-libs:host > /dev/null 2>&1 ||
    fail "no image cdc-slam-libs:host: './cdc test' builds it before the tests (it needs Debian's package registry)"
}

# The image of this build's programs: the libraries layer comes from the engine's cache (no registry here).
build_image() {
  deploy_stage="$work/stage"
  "$repo/deploy/docker/stage.sh" "$build" "$deploy_stage"
  docker build -q -f "$repo/deploy/docker/Dockerfile.host" -t "$CDC_IMAGE" "$deploy_stage" > /dev/null ||
    fail "image build failed (is the runtime library list of this build new? './cdc test' rebuilds the layer)"
}

host_state() {
  local pid
  pid=$(cat "${CDC_DOCKER_DIR:-/var/tmp/cdc-docker}/dockerd.pid")
  {
    nsenter -t "$pid" -n iptables -S
    nsenter -t "$pid" -n iptables -t nat -S
    nsenter -t "$pid" -n ip -o link | sed 's/^[0-9]*: //; s/ .*//' | sort
  } | grep -v '^-A DOCKER -i cdc-docker0' || true
}

run_swarm() {
  "$build/sim/tools/cdc-sim" generate --scenario "$repo/sim/scenarios/kitti05_3robots.yaml" --out "$CDC_DATASET" \
    --max-scans 600 --data "$CDC_DATA_DIR" > "$work/generate.log"
  mkdir -p "$CDC_RESULTS"
  host_state > "$work/host-before.txt"
  dc up -d --no-build > "$work/up.log" 2>&1 || { cat "$work/up.log"; fail "docker-compose up failed"; }
  [[ $(docker network inspect -f '{{.Internal}}' "${project}_swarm") == true ]] || fail "the swarm network has a way out"
  log "swarm up ($(dc ps -q | wc -l) containers); playing 600 sweeps per robot in lock-step"
}

wait_players() {
  local k code
  for k in 0 1 2; do
    code=$(timeout 900 docker wait "$(dc ps -q player-$k)") || fail "player-$k did not finish within 15 min"
    [[ $code == 0 ]] || { dc logs --tail 30 player-$k; fail "player-$k exited with $code"; }
  done
  log "every sweep played"
}

# The final rendezvous: every link up; robots 1 and 2 come back to CENTRALIZED after the dwell time.
rendezvous() {
  dc kill -s SIGUSR1 radio-0 radio-1 radio-2 > /dev/null 2>&1
  local k deadline=$((SECONDS + 90))
  for k in 1 2; do
    until [[ $(tail -1 "$CDC_RESULTS/robot${k}_modes.csv" 2> /dev/null | cut -d, -f5) == CENTRALIZED ]]; do
      ((SECONDS < deadline)) || { cat "$CDC_RESULTS/robot${k}_modes.csv"; fail "robot $k not back in CENTRALIZED"; }
      sleep 1
    done
  done
  sleep 5  # the peers' last corrections
  log "rendezvous: robots 1 and 2 back in CENTRALIZED"
}

stop_and_remove() {
  dc logs --no-color > "$work/compose.log" 2>&1 || true
  dc stop > /dev/null 2>&1 || fail "docker-compose stop failed"
  dc down --remove-orphans > /dev/null 2>&1 || fail "docker-compose down failed"
  [[ -z $(docker ps -aq --filter "label=com.docker.compose.project=$project") ]] || fail "containers left behind"
  [[ -z $(docker network ls -q --filter "label=com.docker.compose.project=$project") ]] || fail "network left behind"
  host_state > "$work/host-after.txt"
  diff "$work/host-before.txt" "$work/host-after.txt" || fail "iptables rules or links left behind (above)"
}

main() {
  preflight
  rm -rf "$work"
  mkdir -p "$work"
  trap 'dc down --remove-orphans > /dev/null 2>&1 || true; docker rmi -f "$CDC_IMAGE" > /dev/null 2>&1 || true' EXIT
  local t0=$SECONDS
  build_image
  log "image $CDC_IMAGE built in $((SECONDS - t0)) s"
  run_swarm
  wait_players
  rendezvous
  stop_and_remove
  python3 "$repo/tests/compose/check_results.py" --results "$CDC_RESULTS" --dataset "$CDC_DATASET" \
    --eval "$build/common/eval/cdc-eval" --robots 3 --central-robot 0 | tee "$build/compose-summary.txt" ||
    fail "results (above)"
  log "passed in $((SECONDS - t0)) s"
  rm -rf "$work"
}

main
