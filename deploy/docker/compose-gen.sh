#!/usr/bin/env bash
# Writes the docker-compose file of a swarm of N robots (the top-level docker-compose.yml is its output for
# three). Per robot: the front-end in a container whose network namespace the robot's other containers share
# (descriptor, loop closure, peer optimiser, the player of its own sensors, the radio emulator). The central
# optimiser and the map share the central's. Every robot talks to its own services on domain 100 over the lo
# of its namespace; the SLAM domain (0) crosses the compose network, which the radio emulators cut.
set -euo pipefail

usage() {
  cat <<USAGE
usage: deploy/docker/compose-gen.sh --robots N [--out FILE]
  Writes the compose file of N robots (1..50; default output: stdout). For N other than 3 it also writes, beside
  FILE, swarm-config/cyclonedds.xml (unicast peers of N robots) and swarm-config/peer_optimiser.yaml, which
  the containers mount. Variables of the generated file (.env or the environment):
    CDC_IMAGE    image (default cdc-slam:latest)
    CDC_DATASET  dataset folder, simulated (cdc-sim generate) or imported (cdc-import) (default ./results/dataset)
    CDC_RESULTS  results folder (default ./results/compose)
USAGE
}

robots="" out=""
while [[ $# -gt 0 ]]; do
  case $1 in
    --robots) robots=${2:?--robots needs a number}; shift 2 ;;
    --out) out=${2:?--out needs a file}; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "compose-gen.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[[ $robots =~ ^[0-9]+$ ]] && ((robots >= 1 && robots <= 50)) ||
  { echo "compose-gen.sh: --robots must be a number from 1 to 50, not '$robots'" >&2; exit 2; }

CENTRAL=198.18.1.10
robot_ip() { echo "198.18.1.$((20 + $1))"; }
if ((robots == 3)); then
  DDS=/opt/cdc/deploy/cyclonedds/compose.xml
  PEER=deploy/swarms/config/peer_liveliness_only.yaml
else
  DDS=/opt/cdc/swarm-config/cyclonedds.xml
  PEER=swarm-config/peer_optimiser.yaml
fi

header() {
  cat <<EOF
# cdc-slam as a docker-compose swarm emulation of $robots robots, written by deploy/docker/compose-gen.sh
# (deploy/README.md). The central node (optimiser + map) and, per robot, the front-end, descriptor, loop
# closure and peer optimiser, a player of the robot's own sensors and a radio emulator (NET_ADMIN) that cuts
# the robot's links following the dataset's radio timeline in the player's sim time. One image:
# deploy/docker/Dockerfile. The compose network is private (198.18.1.0/24, internal: no way out).
#   build/release/sim/tools/cdc-sim generate --scenario sim/scenarios/kitti05_3robots.yaml --out results/dataset
#   docker-compose up --build
version: "3.8"

x-cdc: &cdc
  image: \${CDC_IMAGE:-cdc-slam:latest}
  build:
    context: .
    dockerfile: deploy/docker/Dockerfile
  working_dir: /opt/cdc
  environment:
    CYCLONEDDS_URI: file://$DDS
    CDC_DDS_DOMAIN: "0"
  volumes:
    - \${CDC_DATASET:-./results/dataset}:/data/dataset:ro
    - \${CDC_RESULTS:-./results/compose}:/results
EOF
  ((robots == 3)) || echo "    - ./swarm-config:/opt/cdc/swarm-config:ro"
  cat <<EOF
  init: true
  stop_signal: SIGTERM
  stop_grace_period: 20s

networks:
  swarm:
    driver: bridge
    internal: true
    ipam:
      config:
        - subnet: 198.18.1.0/24

services:
  central:
    <<: *cdc
    command: [cdc-central-optimiser, --config, services/central_optimiser/config/central_optimiser.yaml,
              --graph-out, /results/central.g2o, --stats-out, /results/central.json]
    networks:
      swarm:
        ipv4_address: $CENTRAL

  map:
    <<: *cdc
    network_mode: "service:central"
    depends_on: [central]
    command: [cdc-map, --config, services/map/config/map.yaml, --out, /results/map]
EOF
}

# One robot's containers. $1: robot id; $2: the radio emulator's --ip arguments of every node.
robot() {
  local k=$1 ips=$2 local_dds="file:///opt/cdc/deploy/cyclonedds/loopback.xml"
  local local_args="--local-domain, \"100\", --local-dds-config, $local_dds"
  cat <<EOF

  robot-$k:
    <<: *cdc
    command: [cdc-frontend, --robot, "$k", --config, services/frontend/config/frontend.yaml,
              --domain, "100", --dds-config, $local_dds, --imu-wait-ms, "5000",
              --trajectory-out, /results/robot${k}_odometry.tum]
    networks:
      swarm:
        ipv4_address: $(robot_ip "$k")

  robot-$k-descriptor:
    <<: *cdc
    network_mode: "service:robot-$k"
    depends_on: [robot-$k]
    command: [cdc-descriptor, --robot, "$k", --config, services/descriptor/config/descriptor.yaml,
              $local_args]

  robot-$k-loop-closure:
    <<: *cdc
    network_mode: "service:robot-$k"
    depends_on: [robot-$k]
    command: [cdc-loop-closure, --robot, "$k", --config, services/loop_closure/config/loop_closure.yaml,
              $local_args]

  robot-$k-peer-optimiser:
    <<: *cdc
    network_mode: "service:robot-$k"
    depends_on: [robot-$k]
    command: [cdc-peer-optimiser, --robot, "$k", --config, $PEER,
              $local_args, --mode-out, /results/robot${k}_modes.csv,
              --trajectory-out, /results/robot${k}_keyframes.tum, --stats-out, /results/robot${k}_peer.json]

  player-$k:
    <<: *cdc
    network_mode: "service:robot-$k"
    depends_on: [robot-$k]
    environment:
      CYCLONEDDS_URI: $local_dds
    command: [deploy/docker/after-central.sh, --now, /results/robot${k}_modes.csv.now, --,
              cdc-sim, play, /data/dataset, --robot, "$k", --domain, "100", --lockstep, --wait-readers, "1",
              --clock-file, /results/robot${k}_clock]

  radio-$k:
    <<: *cdc
    network_mode: "service:robot-$k"
    depends_on: [robot-$k]
    cap_add: [NET_ADMIN]
    command: [deploy/docker/radio-emulator.sh, --me, "$k", --periods, /data/dataset/radio_periods.csv,
              --clock, /results/robot${k}_clock, $ips]
EOF
}

swarm_config() {
  local dir=$1 k
  mkdir -p "$dir"
  {
    sed -n '1,/<Peers>/p' "$(dirname "${BASH_SOURCE[0]}")/../cyclonedds/compose.xml"
    echo "        <Peer Address=\"$CENTRAL\"/>"
    for ((k = 0; k < robots; ++k)); do echo "        <Peer Address=\"$(robot_ip "$k")\"/>"; done
    sed -n '/<\/Peers>/,$p' "$(dirname "${BASH_SOURCE[0]}")/../cyclonedds/compose.xml"
  } > "$dir/cyclonedds.xml"
  sed "s/^robots: .*/robots: $robots/" "$(dirname "${BASH_SOURCE[0]}")/../swarms/config/peer_liveliness_only.yaml" \
    > "$dir/peer_optimiser.yaml"
}

ips="--ip, 200=$CENTRAL"
for ((k = 0; k < robots; ++k)); do ips+=", --ip, $k=$(robot_ip "$k")"; done
if [[ -n $out ]]; then exec > "$out"; fi
header
for ((k = 0; k < robots; ++k)); do robot "$k" "$ips"; done
if ((robots != 3)); then swarm_config "$(dirname "${out:-./x}")/swarm-config"; fi
