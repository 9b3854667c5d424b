#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Command chatter of the followers in a run folder of `fnmpc run` (e.g. of
config/scenarios/stress/hover.yaml): standard deviation of the thrust command and of the roll
and pitch references, and the number of steps at the attitude bound, over the NMPC phase from
`--from` s to the start of the landing. One row per run and follower, then the worst.

  /usr/bin/python3 studies/faults-and-safety/chatter.py RUN_DIR [--from 15] [--bound 0.35]

With --sweep, the trade-off of the input-rate weights instead: for each pair
THRUST_RATE,ATTITUDE_REF_RATE it flies the hover scenario (--hover-runs seeds, the worst
chatter) and the triangle (--triangle-runs seeds, formation errors) with those follower
weights and prints one table row per pair.

  /usr/bin/python3 studies/faults-and-safety/chatter.py --sweep 0,0 2,50 5,200 10,1000 [--fnmpc PATH]
"""
import argparse
import csv
import glob
import json
import os
import statistics
import subprocess
import sys


FOLLOWER_WEIGHTS = ("follower: {position: [20, 20, 30], velocity: [2, 2, 2], attitude: 1.0, "
                    "thrust: 0.05, attitude_ref: 5.0, terminal_factor: 5.0}")


def chatter(run_dir, start, bound):
    """Worst thrust SD, roll SD, pitch SD and steps at the bound over runs and followers."""
    runs = sorted(glob.glob(os.path.join(run_dir, "run-*"))) or [run_dir]
    with open(os.path.join(run_dir, "summary.json")) as f:
        top = json.load(f)
    roles = (top.get("run_summaries") or [top])[0]["vehicles"]
    followers = [n for n, v in roles.items() if v.get("role") == "follower"]
    if not followers:
        sys.exit("chatter: no follower in " + run_dir)
    rows, worst = [], [0.0, 0.0, 0.0, 0]
    for r in runs:
        for name in followers:
            with open(os.path.join(r, name + ".csv"), newline="") as f:
                data = [x for x in csv.DictReader(f)
                        if x["phase"] == "nmpc" and float(x["t"]) >= start]
            if len(data) < 2:
                sys.exit(f"chatter: {r}/{name}.csv: fewer than 2 NMPC rows after {start} s")
            th = [float(x["cmd_thrust"]) for x in data]
            ro = [float(x["cmd_roll"]) for x in data]
            pi = [float(x["cmd_pitch"]) for x in data]
            at = sum(1 for x, y in zip(ro, pi) if max(abs(x), abs(y)) >= bound - 1e-6)
            sd = [statistics.pstdev(th), statistics.pstdev(ro), statistics.pstdev(pi)]
            worst = [max(worst[0], sd[0]), max(worst[1], sd[1]), max(worst[2], sd[2]),
                     max(worst[3], at)]
            rows.append((os.path.basename(r), name, sd, at))
    return rows, worst


def variant(path, thrust_rate, attitude_rate, tmp):
    """The scenario with the follower's rate weights set, written beside it (relative file
    paths keep resolving) under a temporary name."""
    with open(path) as f:
        text = f.read()
    if FOLLOWER_WEIGHTS not in text:
        sys.exit(f"chatter: {path}: follower weights line not in the expected form")
    text = text.replace(FOLLOWER_WEIGHTS, FOLLOWER_WEIGHTS[:-1] +
                        f", thrust_rate: {thrust_rate}, attitude_ref_rate: {attitude_rate}}}")
    out = os.path.join(os.path.dirname(path), f".{tmp}-{thrust_rate}-{attitude_rate}.yaml")
    with open(out, "w") as f:
        f.write(text)
    return out


def sweep(a):
    print("| thrust_rate | attitude_ref_rate | hover: thrust SD [N] | roll SD [rad] | pitch SD [rad] "
          "| steps at the bound | triangle: steady-state error [m] | mean error [m] | max error [m] "
          "| fallbacks |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for pair in a.sweep:
        try:
            tr, ar = (float(x) for x in pair.split(","))
        except ValueError:
            sys.exit(f"chatter: --sweep entry '{pair}' is not THRUST_RATE,ATTITUDE_REF_RATE")
        if tr < 0 or ar < 0:
            sys.exit(f"chatter: --sweep entry '{pair}': weights must be >= 0")
        out = {}
        for name, path, runs in (("hover", a.hover, a.hover_runs),
                                 ("triangle", a.triangle, a.triangle_runs)):
            scen = variant(path, tr, ar, "chatter")
            try:
                d = os.path.join(a.out, f"{name}-{tr}-{ar}")
                r = subprocess.run([a.fnmpc, "run", scen, "--runs", str(runs), "-o", d,
                                    "--overwrite"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            finally:
                os.remove(scen)
            if r.returncode != 0:
                sys.exit(f"chatter: fnmpc run {scen} failed:\n{r.stderr[-2000:]}")
            out[name] = d
        _, w = chatter(out["hover"], a.start, a.bound)
        with open(os.path.join(out["triangle"], "summary.json")) as f:
            t = json.load(f)
        print(f"| {tr:g} | {ar:g} | {w[0]:.3f} | {w[1]:.4f} | {w[2]:.4f} | {w[3]} | "
              f"{t['steady_state_formation_error_m']:.4f} | {t['mean_formation_error_m']:.4f} | "
              f"{t['max_formation_error_m']:.3f} | {int(t['fallbacks'])} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", nargs="?")
    ap.add_argument("--sweep", nargs="+", metavar="TR,AR")
    ap.add_argument("--fnmpc", default="build/apps/fnmpc/fnmpc")
    ap.add_argument("--out", default="runs/chatter")
    ap.add_argument("--hover", default="config/scenarios/stress/hover.yaml")
    ap.add_argument("--triangle", default="config/scenarios/triangle.yaml")
    ap.add_argument("--hover-runs", type=int, default=3)
    ap.add_argument("--triangle-runs", type=int, default=10)
    ap.add_argument("--from", dest="start", type=float, default=15.0)
    ap.add_argument("--bound", type=float, default=0.35, help="attitude reference bound [rad]")
    a = ap.parse_args()
    if a.sweep:
        if a.hover_runs < 1 or a.triangle_runs < 1:
            ap.error("--hover-runs and --triangle-runs must be >= 1")
        return sweep(a)
    if not a.run_dir:
        ap.error("give RUN_DIR or --sweep")
    rows, worst = chatter(a.run_dir, a.start, a.bound)
    print("| run | follower | thrust SD [N] | roll SD [rad] | pitch SD [rad] | steps at the bound |")
    print("|---|---|---|---|---|---|")
    for run, name, sd, at in rows:
        print(f"| {run} | {name} | {sd[0]:.3f} | {sd[1]:.4f} | {sd[2]:.4f} | {at} |")
    print(f"| worst | | {worst[0]:.3f} | {worst[1]:.4f} | {worst[2]:.4f} | {worst[3]} |")


if __name__ == "__main__":
    sys.exit(main())
