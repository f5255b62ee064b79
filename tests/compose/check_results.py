#!/usr/bin/env python3
"""Checks the results volume of a compose swarm run (tests/compose/compose_test.sh) and prints its figures:
files written, each robot's mode timeline, each robot's ATE against the dataset's ground truth."""
import argparse
import csv
import json
import os
import subprocess
import sys


def parse_args():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--results", required=True, help="the results volume's folder")
    p.add_argument("--dataset", required=True, help="the dataset folder (robot_K/groundtruth.tum)")
    p.add_argument("--eval", required=True, help="the cdc-eval program")
    p.add_argument("--robots", type=int, required=True, help="number of robots")
    p.add_argument("--central-robot", type=int, default=0, help="the robot carrying the central (never cut off)")
    p.add_argument("--max-ate-fraction", type=float, default=0.005, help="ATE limit as a share of the length")
    return p.parse_args()


def check_files(a, errors):
    needed = ["central.g2o"]
    for k in range(a.robots):
        needed += [f"robot{k}_odometry.tum", f"robot{k}_keyframes.tum", f"robot{k}_modes.csv"]
    for name in needed:
        path = os.path.join(a.results, name)
        if not os.path.isfile(path) or os.path.getsize(path) == 0:
            errors.append(f"{name} not written")


def check_modes(a, k, errors):
    path = os.path.join(a.results, f"robot{k}_modes.csv")
    if not os.path.isfile(path):
        return
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        print(f"robot {k}: sim {int(r['sim_ns']) * 1e-9:7.2f} s  {r['from']} -> {r['to']}  ({r['reason']})")
    to_dist = [i for i, r in enumerate(rows) if r["to"] == "DISTRIBUTED"]
    if k == a.central_robot:
        if to_dist:
            errors.append(f"robot {k} carries the central but switched to DISTRIBUTED")
        return
    if not to_dist:
        errors.append(f"robot {k} never switched to DISTRIBUTED")
    for i in to_dist:
        if "liveliness" not in rows[i]["reason"]:
            errors.append(f"robot {k} switched to DISTRIBUTED for '{rows[i]['reason']}', not a liveliness lapse")
    if to_dist and not any(r["to"] == "CENTRALIZED" for r in rows[to_dist[0] + 1:]):
        errors.append(f"robot {k} never came back to CENTRALIZED")


def check_ate(a, k, kind, errors):
    est = os.path.join(a.results, f"robot{k}_{kind}.tum")
    gt = os.path.join(a.dataset, f"robot_{k}", "groundtruth.tum")
    if not os.path.isfile(est):
        return
    out = subprocess.run([a.eval, "--gt", gt, "--est", est, "--json", "-"], capture_output=True, text=True)
    if out.returncode != 0:
        errors.append(f"cdc-eval failed on {est}: {out.stderr.strip()}")
        return
    t = json.loads(out.stdout[out.stdout.index("{"):])["trajectories"][0]
    ate, length = t["ate_m"]["rmse"], t["gt_length_m"]
    print(f"robot {k} {kind:9}: ATE {ate:.3f} m over {length:.1f} m ({100 * ate / length:.3f} %)")
    if length < 100 or ate >= a.max_ate_fraction * length:
        errors.append(f"robot {k} {kind}: ATE {ate:.3f} m over {length:.1f} m")


def main():
    a = parse_args()
    errors = []
    check_files(a, errors)
    for k in range(a.robots):
        check_modes(a, k, errors)
    for k in range(a.robots):
        for kind in ("odometry", "keyframes"):
            check_ate(a, k, kind, errors)
    for e in errors:
        print("FAIL:", e, file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
