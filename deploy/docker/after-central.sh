#!/usr/bin/env bash
# Runs a command once a robot's peer optimiser is CENTRALIZED with the central alive (its --mode-out
# FILE.now says so): the swarm starts with every robot in the central's range, so that the radio's first
# cut finds a link that was up, as `cdc-launch` does. After --timeout seconds it runs the command anyway.
set -euo pipefail

usage() {
  cat <<USAGE
usage: deploy/docker/after-central.sh --now FILE [--timeout S] -- COMMAND [ARG...]
  --now FILE    the peer optimiser's state file ('<mode> <keyframes> <transitions> <central alive> ...')
  --timeout S   run COMMAND anyway after S seconds (default 120), with a notice
USAGE
}

now="" timeout=120
while [[ $# -gt 0 ]]; do
  case $1 in
    --now) now=${2:?--now needs a file}; shift 2 ;;
    --timeout) timeout=${2:?--timeout needs seconds}; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    --) shift; break ;;
    *) echo "after-central.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[[ -n $now && $# -gt 0 ]] || { usage >&2; exit 2; }
[[ $timeout =~ ^[0-9]+$ ]] || { echo "after-central.sh: --timeout must be whole seconds, not '$timeout'" >&2; exit 2; }

started=$(date +%s)
# A state file older than this script is a previous run's.
ready() {
  local mode _k _t alive
  [[ -s $now && $(stat -c %Y "$now") -ge $started ]] || return 1
  read -r mode _k _t alive _ < "$now" && [[ $mode == CENTRALIZED && $alive == 1 ]]
}
deadline=$((SECONDS + timeout))
until ready; do
  if ((SECONDS >= deadline)); then
    echo "after-central: not CENTRALIZED after $timeout s ($now); starting anyway" >&2
    break
  fi
  sleep 0.2
done
exec "$@"
