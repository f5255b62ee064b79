#!/usr/bin/env bash
# deploy/docker/radio-emulator.sh in a private network namespace of its own (unshare --net): it drops
# the node's traffic to a peer exactly during the out-of-range period of the timeline (wall time, and the
# sim time of a player's clock file), lifts every cut at the rendezvous (SIGUSR1), and leaves no rule behind
# when it stops. Usage: radio_emulator_test.sh REPO
set -euo pipefail
repo=$1
if [[ $(id -u) -ne 0 ]] || ! command -v iptables > /dev/null || ! unshare --net true 2> /dev/null; then
  echo "needs root, iptables and unshare --net: not run" >&2
  exit 77
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf 'a,b,start,end\n0,1,1.0,3.0\n1,2,0.0,100.0\n' > "$tmp/periods.csv"
cat > "$tmp/inner.sh" <<INNER
set -euo pipefail
ip link set lo up
has() { iptables -C INPUT -s "\$1" -j DROP 2>/dev/null && iptables -C OUTPUT -d "\$1" -j DROP 2>/dev/null; }
"$repo/deploy/docker/radio-emulator.sh" --me 0 --periods "$tmp/periods.csv" --ip 0=198.18.5.1 --ip 1=198.18.5.2 \
  --ip 2=198.18.5.3 > "$tmp/radio.log" 2>&1 &
pid=\$!
sleep 0.6
has 198.18.5.2 && { echo "FAIL: blocked before the period"; exit 1; }
sleep 1.6   # t = 2.2 s: inside [1, 3)
has 198.18.5.2 || { echo "FAIL: not blocked during the period"; cat "$tmp/radio.log"; exit 1; }
has 198.18.5.3 && { echo "FAIL: blocked a link of other nodes"; exit 1; }
sleep 1.8   # t = 4.0 s: after the period
has 198.18.5.2 && { echo "FAIL: still blocked after the period"; exit 1; }
sleep 0.2
kill -TERM \$pid
wait \$pid || true
[[ -z \$(iptables -S | grep DROP || true) ]] || { echo "FAIL: rules left behind"; iptables -S; exit 1; }
grep -q "out of range of 1" "$tmp/radio.log" && grep -q "back in range of 1" "$tmp/radio.log" || { echo "FAIL: log"; exit 1; }
# Sim time from a player's clock file ('<stamp ns> <sweeps>'); SIGUSR1 lifts every cut for good.
echo "0 0" > "$tmp/clock"
"$repo/deploy/docker/radio-emulator.sh" --me 0 --periods "$tmp/periods.csv" --ip 1=198.18.5.2 --ip 2=198.18.5.3 \
  --clock "$tmp/clock" > "$tmp/radio2.log" 2>&1 &
pid=\$!
sleep 0.8
has 198.18.5.2 && { echo "FAIL: blocked at clock 0"; exit 1; }
echo "2000000000 20" > "$tmp/clock"
sleep 1
has 198.18.5.2 || { echo "FAIL: not blocked at clock 2 s"; cat "$tmp/radio2.log"; exit 1; }
kill -USR1 \$pid
sleep 1
has 198.18.5.2 && { echo "FAIL: still blocked after the rendezvous"; exit 1; }
has 198.18.5.3 && { echo "FAIL: 1-2 still blocked after the rendezvous"; exit 1; }
kill -TERM \$pid
wait \$pid || true
grep -q "rendezvous" "$tmp/radio2.log" || { echo "FAIL: rendezvous not logged"; exit 1; }
echo "radio emulator OK"
INNER
unshare --net bash "$tmp/inner.sh"
