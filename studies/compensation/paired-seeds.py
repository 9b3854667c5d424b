#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Paired per-seed comparison of two run folders of the same scenario (docs/results.md
"Cooperative mode"), and where the steady-state difference comes from.

    studies/compensation/paired-seeds.py BASE OTHER [FOLLOWER] [LEADER]

For each seed (run-NN in both folders): the top-level steady-state, mean and max formation
error of BASE and OTHER and their paired difference (mean, standard error, t, how many seeds
are worse). Then, over the steady-state samples of FOLLOWER (default `follower`, its first
neighbour): its mean offset (p_j - p_i) - d_j in each folder, the difference OTHER - BASE, and
LEADER's (default `leader`) mean estimated tracking offset (est - ref) over the same samples,
with the correlation and slope of the difference on that offset per axis. A cooperative
follower that follows its leader's plan at a hold moves its offset with what the plan predicts.
"""
import csv
import json
import math
import os
import statistics as st
import sys

import numpy as np
import yaml


def runs(folder):
    return sorted(d for d in os.listdir(folder) if d.startswith("run-"))


def desired(folder, name):
    with open(os.path.join(folder, "scenario.yaml")) as f:
        sc = yaml.safe_load(f)
    for v in sc.get("vehicles", []):
        if v.get("name") == name:
            return np.array(v["neighbours"][0]["desired"], dtype=float)
    raise SystemExit(f"{folder}: no vehicle {name} with neighbours")


def steady_offsets(run_dir, follower, leader, d):
    times, off = set(), []
    with open(os.path.join(run_dir, follower + ".csv")) as f:
        for r in csv.DictReader(f):
            if r["steady"] in ("1", "true"):
                times.add(r["t"])
                off.append([float(r["rel0_" + a]) for a in "xyz"])
    lead = []
    with open(os.path.join(run_dir, leader + ".csv")) as f:
        for r in csv.DictReader(f):
            if r["t"] in times:
                lead.append([float(r["est_" + a]) - float(r["ref_" + a]) for a in "xyz"])
    return np.array(off).mean(0) - d, np.array(lead).mean(0)


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    base, other = sys.argv[1], sys.argv[2]
    follower = sys.argv[3] if len(sys.argv) > 3 else "follower"
    leader = sys.argv[4] if len(sys.argv) > 4 else "leader"
    seeds = [r for r in runs(base) if r in set(runs(other))]
    keys = ["steady_state_formation_error_m", "mean_formation_error_m", "max_formation_error_m"]
    diffs = {k: [] for k in keys}
    d = desired(base, follower)
    shift, lead_off = [], []
    print(f"| seed | {' | '.join(k.replace('_formation_error_m', '') + ' base / other' for k in keys)} | offset shift other - base [m] | leader est - ref [m] |")
    print("|---|" + "---|" * (len(keys) + 2))
    for r in seeds:
        s = [json.load(open(os.path.join(f, r, "summary.json"))) for f in (base, other)]
        cells = []
        for k in keys:
            cells.append(f"{s[0][k]:.4f} / {s[1][k]:.4f}")
            diffs[k].append(s[1][k] - s[0][k])
        ob, lb = steady_offsets(os.path.join(base, r), follower, leader, d)
        oo, _ = steady_offsets(os.path.join(other, r), follower, leader, d)
        shift.append(oo - ob)
        lead_off.append(lb)
        print(f"| {r} | {' | '.join(cells)} | ({', '.join(f'{x:+.4f}' for x in oo - ob)}) | ({', '.join(f'{x:+.4f}' for x in lb)}) |")
    print()
    for k in keys:
        x = diffs[k]
        m = st.mean(x)
        se = st.stdev(x) / math.sqrt(len(x)) if len(x) > 1 else float("nan")
        print(f"{k}: paired difference other - base {1000 * m:+.2f} mm (standard error "
              f"{1000 * se:.2f} mm, t {m / se:+.2f}), other worse in {sum(v > 0 for v in x)} of {len(x)} seeds")
    shift, lead_off = np.array(shift), np.array(lead_off)
    for a in range(3):
        c = np.corrcoef(shift[:, a], lead_off[:, a])[0, 1]
        slope = np.polyfit(lead_off[:, a], shift[:, a], 1)[0]
        print(f"axis {'xyz'[a]}: steady offset shift vs the leader's steady offset (base run): "
              f"correlation {c:.2f}, slope {slope:.2f}")


if __name__ == "__main__":
    main()
