#!/usr/bin/env bash
# Radio emulation inside the compose network: runs beside one robot (sharing its network namespace,
# with NET_ADMIN) and, following the scenario's radio timeline (radio_periods.csv: a,b,start,end in
# seconds of sim time), drops this node's traffic to and from every peer it is out of range of.
# Sim time is the player's (its --clock-file, shared through a volume) or wall time times --rate. SIGUSR1
# starts the final rendezvous: every link comes up and stays up. Rules are removed when a period ends and
# at exit. A clock file older than the emulator (a previous run's) reads as sim time 0.
set -euo pipefail

usage() {
  cat <<USAGE
usage: radio-emulator.sh --me ID --periods radio_periods.csv --ip ID=ADDR [--ip ID=ADDR ...]
                         [--clock FILE | --rate R]
  --me ID        this node's id (robot id, or the central's id)
  --periods F    out-of-range periods of the dataset (cdc-sim generate writes radio_periods.csv)
  --ip ID=ADDR   address of node ID on the compose network (repeat for every node)
  --clock FILE   sim time from the player's clock file ('<stamp ns> <sweeps>'; 0 until it exists)
  --rate R       without --clock: sim seconds per wall second (the player's --rate; default 1)
SIGUSR1: the final rendezvous (every link up from then on). SIGTERM/SIGINT: remove the rules and exit.
USAGE
}
me="" periods="" rate=1 clock=""
declare -A ip=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --me) me=${2:?}; shift 2 ;;
    --periods) periods=${2:?}; shift 2 ;;
    --ip) ip[${2%%=*}]=${2#*=}; shift 2 ;;
    --rate) rate=${2:?}; shift 2 ;;
    --clock) clock=${2:?}; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "radio-emulator: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[[ -n $me && -f $periods && ${#ip[@]} -gt 0 ]] || { usage >&2; exit 2; }

declare -A active=()
block() { iptables -I INPUT -s "$1" -j DROP && iptables -I OUTPUT -d "$1" -j DROP; }
unblock() { iptables -D INPUT -s "$1" -j DROP 2>/dev/null || true; iptables -D OUTPUT -d "$1" -j DROP 2>/dev/null || true; }
cleanup() { for peer in "${!active[@]}"; do unblock "${ip[$peer]}"; done; }
trap cleanup EXIT
trap 'exit 0' INT TERM
rendezvous=0
trap 'rendezvous=1; echo "radio-emulator: node $me, rendezvous: every link up"' USR1

start=$(date +%s.%N)
sim_time() {
  if [[ -n $clock ]]; then
    local stamp=0
    # A clock file older than this emulator is a previous run's.
    [[ -s $clock && $(stat -c %Y "$clock") -ge ${start%.*} ]] && read -r stamp _ < "$clock"
    awk -v s="${stamp:-0}" 'BEGIN { printf "%.3f", s * 1e-9 }'
  else
    awk -v s="$start" -v n="$(date +%s.%N)" -v r="$rate" 'BEGIN { printf "%.3f", (n - s) * r }'
  fi
}

source_=${clock:+clock $clock}
echo "radio-emulator: node $me, $(($(wc -l < "$periods") - 1)) out-of-range periods, ${source_:-rate $rate}"
while true; do
  t=$(sim_time)
  declare -A want=()
  while [[ $rendezvous == 0 ]] && IFS=, read -r a b s e; do
    [[ $a == a ]] && continue
    if awk -v t="$t" -v s="$s" -v e="$e" 'BEGIN { exit !(t >= s && t < e) }'; then
      [[ $a == "$me" ]] && want[$b]=1
      [[ $b == "$me" ]] && want[$a]=1
    fi
  done < "$periods"
  for peer in "${!want[@]}"; do
    if [[ -z ${active[$peer]:-} && -n ${ip[$peer]:-} ]]; then
      block "${ip[$peer]}" && active[$peer]=1 && echo "t=$t s: node $me out of range of $peer"
    fi
  done
  for peer in "${!active[@]}"; do
    if [[ -z ${want[$peer]:-} ]]; then
      unblock "${ip[$peer]}"; unset "active[$peer]"; echo "t=$t s: node $me back in range of $peer"
    fi
  done
  unset want
  sleep 0.5 &
  wait $! || true
done
