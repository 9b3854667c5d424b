#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Formation error and peak speed per graph depth of a run folder (string stability,
docs/results.md "Scale"): depth = fewest formation ties from the leader, as each run's
summary.json gives it per vehicle (`fnmpc run --dry-run` prints it too).

  studies/scale/depth-profile.py RUN_FOLDER [--plot depth.png]

Per depth, over every run and every follower at that depth: the worst steady-state mean
formation error, the worst whole-window max formation error and the peak speed |v| (truth,
whole flight). Prints a Markdown table; --plot also draws it (matplotlib)."""
import argparse
import csv
import json
import math
import sys
from pathlib import Path


def depths(vehicles):
    """Graph depth per vehicle name, as summary.json gives it (fnmpc run: formation::TieDepths;
    vehicles not tied to the leader have none and are left out)."""
    out = {}
    for name, v in vehicles.items():
        if "depth" not in v:
            sys.exit("depth-profile: summary.json has no per-vehicle 'depth' (made by an older "
                     "fnmpc run: rerun it)")
        if v["depth"] is not None:
            out[name] = v["depth"]
    return out


def vehicle_figures(path):
    """Steady-state mean formation error, peak speed of one vehicle's CSV."""
    steady, peak = [], 0.0
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            v = [float(row[k]) for k in ("vx", "vy", "vz")]
            if all(math.isfinite(x) for x in v):
                peak = max(peak, math.sqrt(sum(x * x for x in v)))
            e = float(row["formation_error"])
            if row["steady"] == "1" and math.isfinite(e):
                steady.append(e)
    return (sum(steady) / len(steady) if steady else math.nan), peak


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path, help="run folder of fnmpc run (with run-NN/)")
    ap.add_argument("--plot", type=Path, help="also draw the profile into this PNG")
    args = ap.parse_args()
    runs = sorted(p for p in args.folder.glob("run-*") if (p / "summary.json").is_file())
    if not runs:
        sys.exit(f"depth-profile: {args.folder}: no run-NN/summary.json in it")
    table = {}  # depth -> [followers, steady max, max error, peak speed]
    for run in runs:
        summary = json.loads((run / "summary.json").read_text())
        vehicles = summary["vehicles"]
        for name, d in depths(vehicles).items():
            steady, peak = vehicle_figures(run / f"{name}.csv")
            row = table.setdefault(d, [set(), math.nan, math.nan, 0.0])
            row[0].add(name)
            maxerr = vehicles[name].get("formation_error_max_m")
            if math.isfinite(steady):
                row[1] = steady if math.isnan(row[1]) else max(row[1], steady)
            if isinstance(maxerr, (int, float)):
                row[2] = maxerr if math.isnan(row[2]) else max(row[2], maxerr)
            row[3] = max(row[3], peak)
    print(f"{args.folder}: {len(runs)} run(s)")
    print("| depth | vehicles | steady-state error, worst [m] | max error, worst [m] | peak speed [m/s] |")
    print("|---|---|---|---|---|")
    for d in sorted(table):
        n, s, m, p = table[d]
        fmt = lambda x: "–" if math.isnan(x) else f"{x:.3f}"
        print(f"| {d} | {len(n)} | {fmt(s)} | {fmt(m)} | {p:.2f} |")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        ds = sorted(d for d in table if d > 0)
        fig, ax = plt.subplots(1, 2, figsize=(9, 3.2))
        ax[0].plot(ds, [table[d][1] for d in ds], "o-", label="steady state, worst")
        ax[0].plot(ds, [table[d][2] for d in ds], "s--", label="max, worst")
        ax[0].set_xlabel("graph depth")
        ax[0].set_ylabel("formation error [m]")
        ax[0].legend()
        ax[1].plot(sorted(table), [table[d][3] for d in sorted(table)], "o-")
        ax[1].set_xlabel("graph depth")
        ax[1].set_ylabel("peak speed [m/s]")
        fig.suptitle(str(args.folder.name))
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
