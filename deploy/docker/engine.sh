#!/usr/bin/env bash
# A private Docker engine for the compose test: dockerd with a daemon.json of its own, whose state, socket,
# pid file and containerd live under one directory, whose bridge and address pools lie in 198.19.0.0/16
# (the compose network is 198.18.1.0/24), and which never touches a system Docker (where a system containerd
# answers, dockerd shares it under containerd namespaces of its own). `stop` stops only the
# daemon this script started (by the PID in its pid file) and removes the bridge and iptables chains it made.
set -euo pipefail

DIR=${CDC_DOCKER_DIR:-/var/tmp/cdc-docker}
BRIDGE=cdc-docker0

usage() {
  cat <<USAGE
usage: deploy/docker/engine.sh [--dir DIR] start|stop|status|host
  start    start dockerd (if not running) with DIR/daemon.json; waits until it answers
  stop     stop the dockerd DIR/dockerd.pid names, remove its bridge and the iptables chains it made
  status   exit 0 when the engine answers on its socket
  host     print the DOCKER_HOST value of the engine (unix://DIR/docker.sock)
  --dir D  state directory (default \$CDC_DOCKER_DIR or /var/tmp/cdc-docker); the image cache stays there
Needs root, dockerd (Debian's docker.io) and iptables.
USAGE
}

sock() { echo "$DIR/docker.sock"; }
pid_of() { [[ -s $DIR/dockerd.pid ]] && cat "$DIR/dockerd.pid"; }
running() { local p; p=$(pid_of) && kill -0 "$p" 2>/dev/null; }
answers() { DOCKER_HOST="unix://$(sock)" docker version --format '{{.Server.Version}}' >/dev/null 2>&1; }

write_config() {
  mkdir -p "$DIR/data" "$DIR/exec"
  cat > "$DIR/daemon.json" <<JSON
{
  "data-root": "$DIR/data",
  "exec-root": "$DIR/exec",
  "pidfile": "$DIR/dockerd.pid",
  "hosts": ["unix://$(sock)"],
  "containerd-namespace": "cdc-moby",
  "containerd-plugins-namespace": "cdc-plugins",
  "bridge": "$BRIDGE",
  "default-address-pools": [{"base": "198.19.128.0/17", "size": 24}],
  "ip6tables": false,
  "ipv6": false,
  "userland-proxy": false,
  "log-level": "warn",
  "features": {"buildkit": false}
}
JSON
}

# Docker makes the bridge it is told to use only under its default name, so it is made here, in 198.19.0.0/24.
make_bridge() {
  ip link show "$BRIDGE" >/dev/null 2>&1 && return
  ip link add "$BRIDGE" type bridge
  ip addr add 198.19.0.1/24 dev "$BRIDGE"
  ip link set "$BRIDGE" up
}

start() {
  if running && answers; then echo "engine: already running (pid $(pid_of))"; return; fi
  write_config
  save_host_state
  make_bridge
  local storage=overlay2
  probe_overlay || storage=vfs
  nohup dockerd --config-file "$DIR/daemon.json" --storage-driver "$storage" > "$DIR/dockerd.log" 2>&1 &
  for _ in $(seq 1 120); do
    answers && { echo "engine: dockerd $(pid_of) on $(sock) (storage $storage)"; return; }
    sleep 0.5
  done
  echo "engine: dockerd did not answer within 60 s; log:" >&2
  tail -20 "$DIR/dockerd.log" >&2
  exit 1
}

# dockerd turns IPv4 forwarding on and, when it does, sets the FORWARD policy to DROP: both are put back at stop.
save_host_state() {
  [[ -s $DIR/host-state ]] && return
  printf '%s %s\n' "$(cat /proc/sys/net/ipv4/ip_forward)" \
    "$(iptables -S FORWARD | awk '$1 == "-P" { print $3 }')" > "$DIR/host-state"
}

restore_host_state() {
  [[ -s $DIR/host-state ]] || return 0
  local forward policy
  read -r forward policy < "$DIR/host-state"
  echo "$forward" > /proc/sys/net/ipv4/ip_forward
  iptables -P FORWARD "$policy"
  rm -f "$DIR/host-state"
}

# overlay2 needs an overlay mount that works on the file system of DIR (not on overlay itself).
probe_overlay() {
  local t
  t=$(mktemp -d "$DIR/probe.XXXX")
  mkdir -p "$t"/{l,u,w,m}
  if mount -t overlay overlay -o "lowerdir=$t/l,upperdir=$t/u,workdir=$t/w" "$t/m" 2>/dev/null; then
    umount "$t/m"
    rm -rf "$t"
    return 0
  fi
  rm -rf "$t"
  return 1
}

stop() {
  local p
  if p=$(pid_of) && kill -0 "$p" 2>/dev/null; then
    kill -TERM "$p"
    for _ in $(seq 1 60); do kill -0 "$p" 2>/dev/null || break; sleep 0.5; done
    kill -0 "$p" 2>/dev/null && { echo "engine: dockerd $p still running after 30 s" >&2; exit 1; }
    echo "engine: dockerd $p stopped"
  fi
  rm -f "$DIR/dockerd.pid"
  ip link show "$BRIDGE" >/dev/null 2>&1 && ip link del "$BRIDGE"
  if [[ -n $(pgrep -x dockerd || true) ]]; then
    # Another dockerd (a system Docker) shares the DOCKER chains and needs forwarding: only this engine's rules go.
    remove_rules "$BRIDGE|198\.19\."
    rm -f "$DIR/host-state"
  else
    remove_rules "DOCKER|$BRIDGE|198\.19\."
    remove_chains
    restore_host_state
  fi
}

# dockerd leaves its chains, the jumps to them and its bridge's forward and masquerade rules at exit.
# Deletes every filter and nat rule matching the extended regular expression $1.
remove_rules() {
  local table rule
  for table in filter nat; do
    iptables -t "$table" -S | grep -E "^-A .*($1)" | sed 's/^-A/-D/' |
      while read -r rule; do eval "iptables -t $table $rule"; done
  done
}

remove_chains() {
  local table chain
  for table in filter nat; do
    for chain in DOCKER DOCKER-USER DOCKER-ISOLATION-STAGE-1 DOCKER-ISOLATION-STAGE-2; do
      iptables -t "$table" -F "$chain" 2>/dev/null || true
    done
    for chain in DOCKER DOCKER-USER DOCKER-ISOLATION-STAGE-1 DOCKER-ISOLATION-STAGE-2; do
      iptables -t "$table" -X "$chain" 2>/dev/null || true
    done
  done
}

while [[ $# -gt 0 ]]; do
  case $1 in
    --dir) DIR=${2:?--dir needs a directory}; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    start|stop|status|host) cmd=$1; shift ;;
    *) echo "engine.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[[ -n ${cmd:-} ]] || { usage >&2; exit 2; }
[[ $(id -u) -eq 0 ]] || { echo "engine.sh: needs root (dockerd runs as root)" >&2; exit 1; }
case $cmd in
  start) start ;;
  stop) stop ;;
  status) running && answers ;;
  host) echo "unix://$(sock)" ;;
esac
