#!/usr/bin/env bash
# Deployment artefacts: the systemd installer renders a robot's units and Cyclone DDS configuration
# into a scratch root (systemd-analyze verifies the units), rejects bad arguments with a reason,
# and docker-compose validates the compose file. Usage: deploy_test.sh REPO BUILD_DIR
set -euo pipefail
repo=$1 build=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# 1. systemd installer into a scratch root.
"$repo/deploy/systemd/install.sh" --robot 2 --interface wlan0 --peer 198.18.0.1 --peer 198.18.0.3 --domain 7 \
  --build "$build" --root "$tmp/root" > "$tmp/install.log"
for f in opt/cdc-slam/bin/cdc-frontend opt/cdc-slam/bin/cdc-peer-optimiser etc/cdc-slam/frontend.yaml \
         etc/cdc-slam/cyclonedds-robot.xml etc/cdc-slam/robot.env etc/systemd/system/cdc-frontend@.service \
         etc/systemd/system/cdc-robot@.target; do
  [[ -e $tmp/root/$f ]] || fail "$f not installed"
done
xml=$tmp/root/etc/cdc-slam/cyclonedds-robot.xml
python3 -c "import sys, xml.dom.minidom; xml.dom.minidom.parse(sys.argv[1])" "$xml" || fail "rendered XML is not well-formed"
grep -q '<NetworkInterface name="wlan0"/>' "$xml" || fail "interface not rendered"
grep -q '<Peer Address="198.18.0.1"/>' "$xml" && grep -q '<Peer Address="198.18.0.3"/>' "$xml" || fail "peers not rendered"
grep -q '<AllowMulticast>false</AllowMulticast>' "$xml" || fail "multicast not off"
grep -q 'CDC_DDS_DOMAIN=7' "$tmp/root/etc/cdc-slam/robot.env" || fail "domain not written"
grep -q 'CDC_LOCAL_DOMAIN=100' "$tmp/root/etc/cdc-slam/robot.env" || fail "local domain not written"
grep -q '<NetworkInterface name="lo"/>' "$tmp/root/etc/cdc-slam/cyclonedds-local.xml" || fail "local domain not on lo"
# The robot's own traffic stays on its local domain: the front-end lives there, the others join it.
grep -q -- "--domain \${CDC_LOCAL_DOMAIN} --dds-config file://$tmp/root/etc/cdc-slam/cyclonedds-local.xml" \
  "$tmp/root/etc/systemd/system/cdc-frontend@.service" || fail "front-end not on the local domain"
for u in descriptor loop-closure peer-optimiser; do
  grep -q -- "--local-domain \${CDC_LOCAL_DOMAIN} --local-dds-config" "$tmp/root/etc/systemd/system/cdc-$u@.service" \
    || fail "$u does not join the local domain"
done
! grep -q '@[A-Z]*@' "$tmp"/root/etc/systemd/system/* "$xml" || fail "placeholders left in rendered files"
# The rendered units start the right binaries with the robot's instance.
grep -q "ExecStart=$tmp/root/opt/cdc-slam/bin/cdc-loop-closure --robot %i" "$tmp/root/etc/systemd/system/cdc-loop-closure@.service" \
  || fail "loop-closure unit does not start its binary"
# A restarted loop-closure service goes on numbering its loops from its state file.
grep -q -- "--state-file $tmp/root/var/lib/cdc-slam/loop-closure-%i.state" "$tmp/root/etc/systemd/system/cdc-loop-closure@.service" \
  || fail "loop-closure unit keeps no loop numbering state"
if command -v systemd-analyze > /dev/null; then
  for u in frontend descriptor loop-closure peer-optimiser; do
    cp "$tmp/root/etc/systemd/system/cdc-$u@.service" "$tmp/cdc-$u@2.service"
  done
  systemd-analyze verify --man=no "$tmp"/cdc-*@2.service || fail "systemd-analyze verify rejects the rendered units"
fi
# Bad arguments are named.
if "$repo/deploy/systemd/install.sh" --robot 300 --interface wlan0 --peer 1.2.3.4 --root "$tmp/x" 2> "$tmp/err"; then fail "robot 300 accepted"; fi
grep -q "robot must be a number" "$tmp/err" || fail "no reason for a bad robot id"
if "$repo/deploy/systemd/install.sh" --robot 1 --interface wlan0 --root "$tmp/x" 2> "$tmp/err"; then fail "no peers accepted"; fi
grep -q "at least one --peer" "$tmp/err" || fail "no reason for missing peers"
if "$repo/deploy/systemd/install.sh" --robot 1 --interface wlan0 --peer 1.2.3.4 --domain 5 --local-domain 5 --root "$tmp/x" \
  2> "$tmp/err"; then fail "local domain equal to the radio domain accepted"; fi
grep -q "local-domain must differ" "$tmp/err" || fail "no reason for a local domain equal to the radio domain"

# 2. docker-compose file (no engine needed to validate).
if command -v docker-compose > /dev/null; then
  (cd "$repo" && docker-compose -f docker-compose.yml config -q) || fail "docker-compose.yml does not validate"
  services=$(cd "$repo" && docker-compose -f docker-compose.yml config --services)
  for s in central map player-0 robot-0 robot-0-descriptor robot-0-loop-closure robot-0-peer-optimiser radio-0 robot-2; do
    grep -qx "$s" <<< "$services" || fail "compose service $s missing"
  done
  # Every binary the compose file runs is one the build makes.
  for b in $(cd "$repo" && docker-compose -f docker-compose.yml config | sed -n 's/^ *- \(cdc-[a-z-]*\)$/\1/p' | sort -u); do
    [[ -n $(find "$build" -name "$b" -type f -perm -u+x -print -quit) ]] || fail "compose runs $b, which the build does not make"
  done
  grep -q '^RUN ./cdc build --preset release' "$repo/deploy/docker/Dockerfile" || fail "the Dockerfile does not build with ./cdc build"
  # The compose file is the generator's for three robots; the generator's file for five validates too.
  diff <("$repo/deploy/docker/compose-gen.sh" --robots 3) "$repo/docker-compose.yml" > /dev/null ||
    fail "docker-compose.yml differs from 'deploy/docker/compose-gen.sh --robots 3'"
  "$repo/deploy/docker/compose-gen.sh" --robots 5 --out "$tmp/five/docker-compose.yml" 2> /dev/null &&
    fail "compose-gen.sh wrote into a missing folder"
  mkdir -p "$tmp/five"
  "$repo/deploy/docker/compose-gen.sh" --robots 5 --out "$tmp/five/docker-compose.yml"
  (cd "$tmp/five" && docker-compose config -q) || fail "the five-robot compose file does not validate"
  grep -q '198.18.1.24' "$tmp/five/swarm-config/cyclonedds.xml" || fail "the five-robot DDS peers miss robot 4"
  if "$repo/deploy/docker/compose-gen.sh" --robots 0 2> "$tmp/err"; then fail "zero robots accepted"; fi
  grep -q "from 1 to 50" "$tmp/err" || fail "no reason for a bad number of robots"
else
  echo "docker-compose not installed (deploy/install-deps.sh installs it): compose checks not run" >&2
  exit 77
fi
echo "deploy artefacts OK"
