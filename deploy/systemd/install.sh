#!/usr/bin/env bash
# Installs one robot's cdc-slam services on an embedded Linux robot (systemd): binaries, configurations,
# the robot's Cyclone DDS configuration (rendered from cyclonedds-robot.xml.in) and the units
# cdc-{frontend,descriptor,loop-closure,peer-optimiser}@N.service under cdc-robot@N.target.
set -euo pipefail

usage() {
  cat <<USAGE
usage: deploy/systemd/install.sh --robot N --interface IF --peer ADDR [--peer ADDR ...] [options]
  --robot N          this robot's id (0..254)
  --interface IF     the radio interface DDS uses (e.g. wlan0)
  --peer ADDR        unicast address of the central node or another robot (repeat; at least one)
  --domain D         DDS domain id of the radio (default 0)
  --local-domain L   the robot's own DDS domain, on lo: sensors, keyframes, corrections, its own
                     descriptors and loops never cross the radio (default 100; must differ from D)
  --build DIR        build folder with the binaries (default: build/release)
  --prefix DIR       where binaries go (default /opt/cdc-slam)
  --etc DIR          where configurations go (default /etc/cdc-slam)
  --root DIR         install below DIR instead of / (for packaging and tests; implies --no-systemctl)
  --no-systemctl     do not run systemctl daemon-reload / enable
  --help             this text
USAGE
}

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
robot="" iface="" domain=0 local_domain=100 build="$repo/build/release" prefix=/opt/cdc-slam etc=/etc/cdc-slam root="" systemctl=1
peers=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --robot) robot=${2:?--robot needs a value}; shift 2 ;;
    --interface) iface=${2:?--interface needs a value}; shift 2 ;;
    --peer) peers+=("${2:?--peer needs a value}"); shift 2 ;;
    --domain) domain=${2:?--domain needs a value}; shift 2 ;;
    --local-domain) local_domain=${2:?--local-domain needs a value}; shift 2 ;;
    --build) build=${2:?--build needs a value}; shift 2 ;;
    --prefix) prefix=${2:?--prefix needs a value}; shift 2 ;;
    --etc) etc=${2:?--etc needs a value}; shift 2 ;;
    --root) root=${2:?--root needs a value}; systemctl=0; shift 2 ;;
    --no-systemctl) systemctl=0; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "install.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
fail() { echo "install.sh: $*" >&2; exit 2; }
[[ $robot =~ ^[0-9]+$ && $robot -le 254 ]] || fail "--robot must be a number 0..254 (got '$robot')"
[[ -n $iface && $iface =~ ^[A-Za-z0-9_.:-]+$ ]] || fail "--interface must name a network interface (got '$iface')"
[[ ${#peers[@]} -gt 0 ]] || fail "at least one --peer is needed (unicast discovery; multicast is off)"
for p in "${peers[@]}"; do
  [[ $p =~ ^[A-Za-z0-9.:-]+$ ]] || fail "--peer '$p' is not an address or host name"
done
[[ $domain =~ ^[0-9]+$ && $domain -le 232 ]] || fail "--domain must be 0..232 (got '$domain')"
[[ $local_domain =~ ^[0-9]+$ && $local_domain -le 232 ]] || fail "--local-domain must be 0..232 (got '$local_domain')"
[[ $local_domain -ne $domain ]] || fail "--local-domain must differ from --domain ($domain): the radio would carry the robot's own traffic"
bins=(cdc-frontend cdc-descriptor cdc-loop-closure cdc-peer-optimiser)
declare -A bin_path=(
  [cdc-frontend]=services/frontend/cdc-frontend [cdc-descriptor]=services/descriptor/cdc-descriptor
  [cdc-loop-closure]=services/loop_closure/cdc-loop-closure [cdc-peer-optimiser]=services/peer_optimiser/cdc-peer-optimiser)
for b in "${bins[@]}"; do
  [[ -x $build/${bin_path[$b]} ]] || fail "$build/${bin_path[$b]} not found: build first (./cdc build --preset release)"
done

R=${root%/}
state=/var/lib/cdc-slam
install -d "$R$prefix/bin" "$R$etc" "$R/etc/systemd/system" "$R$state"
for b in "${bins[@]}"; do install -m 0755 "$build/${bin_path[$b]}" "$R$prefix/bin/$b"; done
install -m 0644 "$repo/services/frontend/config/frontend.yaml" "$repo/services/descriptor/config/descriptor.yaml" \
  "$repo/services/loop_closure/config/loop_closure.yaml" "$repo/services/peer_optimiser/config/peer_optimiser.yaml" "$R$etc/"
peer_lines=""
for p in "${peers[@]}"; do peer_lines+="        <Peer Address=\"$p\"/>"$'\n'; done
peer_lines=${peer_lines%$'\n'}
xml=$(<"$here/cyclonedds-robot.xml.in")
xml=${xml//@ROBOT@/$robot}
xml=${xml//@INTERFACE@/$iface}
xml=${xml//@PEERS@/$peer_lines}
printf '%s\n' "$xml" > "$R$etc/cyclonedds-robot.xml"
install -m 0644 "$repo/deploy/cyclonedds/loopback.xml" "$R$etc/cyclonedds-local.xml"
printf 'CDC_DDS_DOMAIN=%s\nCDC_LOCAL_DOMAIN=%s\nCDC_ROBOT=%s\n' "$domain" "$local_domain" "$robot" > "$R$etc/robot.env"
for unit in "$here"/cdc-*@.service.in; do
  out="$R/etc/systemd/system/$(basename "${unit%.in}")"
  sed -e "s|@PREFIX@|$R$prefix|g" -e "s|@ETC@|$R$etc|g" -e "s|@STATE@|$R$state|g" "$unit" > "$out"
done
install -m 0644 "$here/cdc-robot@.target" "$R/etc/systemd/system/"
echo "installed robot $robot's services below ${R:-/} (interface $iface, peers ${peers[*]}, domain $domain, local domain $local_domain)"
if [[ $systemctl -eq 1 ]]; then
  systemctl daemon-reload
  systemctl enable "cdc-robot@$robot.target"
  echo "enabled cdc-robot@$robot.target: start it with 'systemctl start cdc-robot@$robot.target'"
fi
