#!/usr/bin/env bash
# Proves that cdc-slam's DDS traffic stays on loopback. In a private network namespace that
# this test creates, with a veth pair (198.18.0.1 <-> 198.18.0.2) standing in for a real
# network, it runs DDS processes with deploy/cyclonedds/loopback.xml and captures UDP on the
# veth: zero packets must appear there (while packets do flow on lo). A control run with a
# configuration bound to the veth must show packets, so the capture could see a leak.
# Usage: loopback_only_test.sh LOOPBACK_XML WRITER_BIN PUBSUB_TEST_BIN
# Exit 77 (skipped) only when the machine forbids network namespaces or tcpdump is missing.
set -euo pipefail

XML=${1:?loopback config}
WRITER=${2:?writer helper}
PUBSUB=${3:?pubsub test binary}

if [ "${CDC_IN_TEST_NETNS:-0}" != 1 ]; then
  command -v tcpdump >/dev/null || { echo "SKIP: tcpdump is not installed (deploy/install-deps.sh installs it)"; exit 77; }
  if [ "$(id -u)" -eq 0 ] && unshare --net true 2>/dev/null; then
    exec env CDC_IN_TEST_NETNS=1 unshare --net -- "$0" "$@"
  elif unshare --user --map-root-user --net true 2>/dev/null; then
    exec env CDC_IN_TEST_NETNS=1 unshare --user --map-root-user --net -- "$0" "$@"
  fi
  echo "SKIP: this machine forbids creating a network namespace (unshare --net), needed to add a test interface"
  exit 77
fi

# Everything below runs in the private namespace: its links vanish with it.
WORK=$(mktemp -d)
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
  ip link del cdcv0 2>/dev/null || true
  rm -rf "$WORK"
}
trap cleanup EXIT

ip link set lo up
ip link add cdcv0 type veth peer name cdcv1
ip addr add 198.18.0.1/24 dev cdcv0
ip link set cdcv0 up
# The far end lives in a second namespace (held by a sleeping process), so packets to
# 198.18.0.2 really cross the link instead of being routed over lo.
unshare --net sleep 600 &
PEER=$!
PIDS+=("$PEER")
sleep 0.2
ip link set cdcv1 netns "$PEER"
nsenter -t "$PEER" -n ip addr add 198.18.0.2/24 dev cdcv1
nsenter -t "$PEER" -n ip link set cdcv1 up
nsenter -t "$PEER" -n ip link set lo up

start_capture() {  # iface file
  tcpdump -i "$1" -n -U -w "$2" udp >/dev/null 2>&1 &
  CAPTURES+=($!)
  PIDS+=($!)
  sleep 0.5
}

CAPTURES=()
stop_captures() {
  for p in "${CAPTURES[@]}"; do kill -INT "$p" 2>/dev/null || true; done
  for p in "${CAPTURES[@]}"; do wait "$p" 2>/dev/null || true; done
  CAPTURES=()
}

count() { tcpdump -n -r "$1" 2>/dev/null | wc -l; }

# Runs DDS: two writer processes discovering each other, plus a full pub/sub test.
run_dds() {  # uri domain
  local uri=$1 domain=$2
  CYCLONEDDS_URI=$uri "$WRITER" --topic cdc/test/netcheck --lease-ms 500 --period-ms 50 --domain "$domain" >/dev/null &
  local w1=$!
  CYCLONEDDS_URI=$uri "$WRITER" --topic cdc/test/netcheck --lease-ms 500 --period-ms 50 --domain "$domain" >/dev/null &
  local w2=$!
  CYCLONEDDS_URI=$uri CDC_DDS_DOMAIN=$domain "$PUBSUB" --gtest_filter='PubSub.*' >"$WORK/pubsub_$domain.log" 2>&1 || {
    echo "pub/sub test failed under $uri:"; cat "$WORK/pubsub_$domain.log"; kill $w1 $w2; return 1; }
  sleep 1
  kill -TERM $w1 $w2
  wait $w1 $w2 || true
}

echo "== loopback configuration: $XML"
start_capture cdcv0 "$WORK/veth0.pcap"
start_capture lo "$WORK/lo.pcap"
run_dds "file://$XML" 11
stop_captures
on_veth=$(count "$WORK/veth0.pcap")
on_lo=$(count "$WORK/lo.pcap")
echo "UDP packets: lo=$on_lo veth=$on_veth"

echo "== control: a configuration bound to the veth"
cat >"$WORK/veth.xml" <<XML
<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any">
  <General><Interfaces><NetworkInterface address="198.18.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast></General>
  <Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer Address="198.18.0.2"/></Peers></Discovery>
</Domain></CycloneDDS>
XML
start_capture cdcv0 "$WORK/ctl.pcap"
run_dds "file://$WORK/veth.xml" 12
stop_captures
control=$(count "$WORK/ctl.pcap")
echo "UDP packets on the veth in the control run: $control"

fail=0
[ "$on_lo" -gt 0 ] || { echo "FAIL: no DDS traffic on lo: the check measured nothing"; fail=1; }
[ "$on_veth" -eq 0 ] || { echo "FAIL: $on_veth DDS packets left loopback"; fail=1; }
[ "$control" -gt 0 ] || { echo "FAIL: the control run showed no packets: the capture cannot see a leak"; fail=1; }
[ $fail -eq 0 ] && echo "PASS: DDS traffic stayed on loopback"
exit $fail
