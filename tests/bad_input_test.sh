#!/usr/bin/env bash
# The tools refuse what they cannot do: numbers out of range or not finite, files that disagree with each other,
# a solver that failed. Each case runs a binary with bad input and checks that it exits non-zero and says what
# is wrong; the cases that are legitimate exit 0 and say what they did. Binaries come from the environment
# (CDC_SIM_BIN, CDC_ODOMETRY_BIN, CDC_PGO_BIN, CDC_LOOPS_BIN). Usage: bad_input_test.sh
set -uo pipefail
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}

# expect EXIT WHAT SUBSTRING COMMAND...: the command ends within 60 s, with status 0 when EXIT is "ok" and
# non-zero when it is "error", and its output holds SUBSTRING.
expect() {
  local want=$1 what=$2 text=$3
  shift 3
  local out rc
  out=$(timeout 60 "$@" 2>&1)
  rc=$?
  if [[ $rc -eq 124 ]]; then
    fail "$what: still running after 60 s"
  elif [[ $want == error && $rc -eq 0 ]]; then
    fail "$what: exit 0"
  elif [[ $want == ok && $rc -ne 0 ]]; then
    fail "$what: exit $rc: $out"
  elif [[ $out != *"$text"* ]]; then
    fail "$what: exit $rc without '$text' in: $out"
  elif [[ $want == error ]]; then
    echo "ok: $what (exit $rc)"
  else
    echo "ok: $what"
  fi
}

# expect_error WHAT SUBSTRING COMMAND...: the command exits non-zero and its output holds SUBSTRING.
expect_error() { expect error "$@"; }

# expect_ok WHAT SUBSTRING COMMAND...: the command exits 0 and its output holds SUBSTRING.
expect_ok() { expect ok "$@"; }

small_scenario() {
  printf 'name: tiny\nseed: 2\ntrajectories:\n  source: procedural\n  pattern: crossing\n  robots: %s\n' "$1"
  printf '  duration_s: %s\n  size_m: 60\nradio:\n  central_robot: 0\n' "$2"
}

# --- 4. Unbounded work from one number -------------------------------------------------------------
small_scenario 2 20 > "$tmp/tiny.yaml"
printf 'duration_s: 1e12\n' > "$tmp/long.yaml"
expect_error "scenario duration_s 1e12" "duration_s: 1e12 is invalid (expected in [0, 7200])" \
  "$CDC_SIM_BIN" radio --scenario "$tmp/long.yaml"
small_scenario 2 1e12 > "$tmp/long_mission.yaml"
expect_error "mission duration 1e12" "trajectories.duration_s: 1e12 is invalid" \
  "$CDC_SIM_BIN" radio --scenario "$tmp/long_mission.yaml"
expect_error "generate --max-scans -1" "--max-scans: -1 is outside the allowed range" \
  "$CDC_SIM_BIN" generate --scenario "$tmp/tiny.yaml" --out "$tmp/never" --max-scans -1
for bad in "--rate nan" "--rate -1" "--rate inf" "--lockstep-timeout nan" "--max-scans -1"; do
  # shellcheck disable=SC2086  # the option and its value are two words
  expect_error "play $bad" "${bad%% *}: " "$CDC_SIM_BIN" play "$tmp" $bad
done

# SIGTERM ends a long generate within a second or two: no dataset, the signal's exit code.
small_scenario 3 3600 > "$tmp/hour.yaml"
"$CDC_SIM_BIN" generate --scenario "$tmp/hour.yaml" --out "$tmp/hour" > "$tmp/hour.log" 2>&1 &
sim=$!
sleep 2
kill -TERM $sim
for _ in $(seq 50); do
  kill -0 $sim 2> /dev/null || break
  sleep 0.1
done
if kill -0 $sim 2> /dev/null; then
  fail "cdc-sim generate still running 5 s after SIGTERM"
  kill -KILL $sim
  wait $sim 2> /dev/null
else
  wait $sim
  rc=$?
  [[ $rc -eq 143 ]] || fail "cdc-sim generate after SIGTERM: exit $rc (expected 143): $(cat "$tmp/hour.log")"
  [[ ! -e $tmp/hour ]] || fail "cdc-sim generate left a dataset after SIGTERM"
  [[ $rc -eq 143 && ! -e $tmp/hour ]] && echo "ok: SIGTERM ends generate (exit 143)"
fi

# --- 5. Silent partial work -------------------------------------------------------------------------
"$CDC_SIM_BIN" generate --scenario "$tmp/tiny.yaml" --out "$tmp/ds" --max-scans 6 > /dev/null || fail "generate"
head -n 3 "$tmp/ds/robot_0/times.txt" > "$tmp/times" && mv "$tmp/times" "$tmp/ds/robot_0/times.txt"
expect_error "odometry with a short times.txt" "times.txt: lists 3 sweeps but" \
  "$CDC_ODOMETRY_BIN" "$tmp/ds" --robot 0 --lidar-only
expect_error "play with a short times.txt" "times.txt: lists 3 sweeps but" "$CDC_SIM_BIN" play "$tmp/ds" --rate 0

q='0 0 0 1'
info='1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1'
printf 'VERTEX_SE3:QUAT 0 0 0 0 %s\nVERTEX_SE3:QUAT 1 1 0 0 %s\nVERTEX_SE3:QUAT 1 2 0 0 %s\n' "$q" "$q" "$q" \
  > "$tmp/dup.g2o"
printf 'EDGE_SE3:QUAT 0 1 1 0 0 %s %s\n' "$q" "$info" >> "$tmp/dup.g2o"
expect_error "g2o duplicate vertex" "vertex 1 declared again with a different pose (first on line 2)" \
  "$CDC_PGO_BIN" "$tmp/dup.g2o"
printf 'VERTEX_SE3:QUAT 0 0 0 0 %s\nVERTEX_SE3:QUAT 1 1 0 0 %s\n' "$q" "$q" > "$tmp/undeclared.g2o"
printf 'EDGE_SE3:QUAT 0 1 1 0 0 %s %s\nEDGE_SE3:QUAT 1 2 1 0 0 %s %s\n' "$q" "$info" "$q" "$info" \
  >> "$tmp/undeclared.g2o"
expect_error "g2o edge to an undeclared vertex" "edges name 1 vertices no VERTEX line declares (2 the first)" \
  "$CDC_PGO_BIN" "$tmp/undeclared.g2o"
printf 'EDGE_SE3:QUAT 0 1 1 0 0 %s %s\nEDGE_SE3:QUAT 1 2 1 0 0 %s %s\n' "$q" "$info" "$q" "$info" > "$tmp/edges.g2o"
expect_ok "g2o without vertex lines" "declares no VERTEX lines: all 3 poses are initialised from the edges" \
  "$CDC_PGO_BIN" "$tmp/edges.g2o"
# A cost that overflows: Ceres cannot evaluate it, so the run fails and --out is not written.
huge='1e300 0 0 0 0 0 1e300 0 0 0 0 1e300 0 0 0 1e300 0 0 1e300 0 1e300'
printf 'VERTEX_SE3:QUAT 0 0 0 0 %s\nVERTEX_SE3:QUAT 1 1e9 0 0 %s\nEDGE_SE3:QUAT 0 1 1 0 0 %s %s\n' "$q" "$q" "$q" \
  "$huge" > "$tmp/overflow.g2o"
expect_error "pgo whose cost overflows" "the solver failed" \
  "$CDC_PGO_BIN" "$tmp/overflow.g2o" --init file --out "$tmp/overflow_out.g2o"
[[ ! -e $tmp/overflow_out.g2o ]] || fail "cdc-pgo wrote --out after the solver failed"
# Residuals that overflow: Ceres cannot evaluate the problem at all.
sed -i 's/^VERTEX_SE3:QUAT 1 1e9 /VERTEX_SE3:QUAT 1 1e300 /' "$tmp/overflow.g2o"
expect_error "pgo whose residuals overflow" "the solver failed (Residual and Jacobian evaluation failed.)" \
  "$CDC_PGO_BIN" "$tmp/overflow.g2o" --init file --out "$tmp/overflow_out.g2o"
[[ ! -e $tmp/overflow_out.g2o ]] || fail "cdc-pgo wrote --out after the solver failed"

# PCM: robots a and b with odometry and two consistent loops; one loop to robot q, which has no trajectory; and a
# robot whose ids carry 'A' in the top byte (outside a..z), whose ids are written back as they were read.
key() { python3 -c "print((ord('$1') << 56) | $2)"; }
{
  for r in a b A; do
    for i in 0 1 2 3; do
      printf 'VERTEX_SE3:QUAT %s %s 0 0 %s\n' "$(key $r "$i")" "$i" "$q"
    done
    for i in 0 1 2; do
      printf 'EDGE_SE3:QUAT %s %s 1 0 0 %s %s\n' "$(key $r "$i")" "$(key $r $((i + 1)))" "$q" "$info"
    done
  done
  printf 'VERTEX_SE3:QUAT %s 0 0 0 %s\n' "$(key q 7)" "$q"
  for i in 0 2; do
    printf 'EDGE_SE3:QUAT %s %s 0 0 0 %s %s\n' "$(key a "$i")" "$(key b "$i")" "$q" "$info"
    printf 'EDGE_SE3:QUAT %s %s 0 0 0 %s %s\n' "$(key a "$i")" "$(key A "$i")" "$q" "$info"
  done
  printf 'EDGE_SE3:QUAT %s %s 0 0 0 %s %s\n' "$(key a 1)" "$(key q 7)" "$q" "$info"
} > "$tmp/pcm.g2o"
out=$("$CDC_LOOPS_BIN" pcm "$tmp/pcm.g2o" --json 2>&1)
echo "pcm: $out"
python3 - "$out" "$(key a 1)" "$(key q 7)" "$(key A 0)" "$(key A 2)" << 'EOF' || fail "cdc-loops pcm: $out"
import json, sys
j = json.loads(sys.argv[1].splitlines()[-1])
a1, q7, A0, A2 = (int(x) for x in sys.argv[2:6])
accepted = [tuple(p) for p in j["accepted"]]
assert (a1, q7) not in accepted, "a loop to robot q, which has no trajectory, was kept"
assert [a1, q7] in j["rejected"], "the loop to robot q is neither kept nor rejected"
ends = {e for p in j["accepted"] + j["rejected"] for e in p}
assert A0 in ends and A2 in ends, "ids with 'A' in the top byte were not written back as read: %s" % sorted(ends)
EOF

# --- 6. Values that pass but cannot work ------------------------------------------------------------
"$CDC_SIM_BIN" generate --scenario "$tmp/tiny.yaml" --out "$tmp/nan" --max-scans 4 > /dev/null
sed -i '3s/^\([^,]*\),[^,]*,/\1,nan,/' "$tmp/nan/robot_0/imu.csv"
expect_error "a NaN in imu.csv" "imu.csv:3: a value is not a finite number" "$CDC_ODOMETRY_BIN" "$tmp/nan" --robot 0
"$CDC_SIM_BIN" generate --scenario "$tmp/tiny.yaml" --out "$tmp/calib" --max-scans 4 > /dev/null
sed -i 's/position: \[[^]]*\]/position: [nan, 0, 0]/' "$tmp/calib/robot_0/calib.yaml"
expect_error "a NaN in calib.yaml" "robot_0/calib.yaml:4: T_lidar_imu holds a value that is not a finite number" \
  "$CDC_ODOMETRY_BIN" "$tmp/calib" --robot 0
printf 'T_lidar_imu: {position: [0, 0], orientation: [0, 0, 0, 1]}\n' > "$tmp/calib/robot_0/calib.yaml"
expect_error "a short position in calib.yaml" "robot_0/calib.yaml:1: T_lidar_imu needs" \
  "$CDC_ODOMETRY_BIN" "$tmp/calib" --robot 0

[[ $failures -eq 0 ]] || {
  echo "$failures failures" >&2
  exit 1
}
echo "all bad input refused"
