#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Compensation levels side by side (docs/results.md "Beating the wake").

Reads run folders of `fnmpc run` (summary.json at the top, run-NN/<vehicle>.csv) and prints
one markdown row per folder: the aggregate steady-state / mean / max formation error (worst
follower, mean over the runs, range of the runs) and the vertical part of the mean error,
mean over each follower's window of |(p_j - p_i)_z - d_j,z| for its first neighbour (the
CSV's rel0_z against the scenario's desired offset), worst follower, mean over the runs.

    studies/compensation/compensation-table.py runs/wake/triangle-none runs/wake/triangle-observer ...

With --plot RUN_DIR/run-NN/VEHICLE.csv OUT.png: the vehicle's estimated external force
(est_f*) against the simulator's aerodynamic force (aero_f*) over time.
"""
import argparse
import csv
import glob
import json
import math
import os
import sys

import yaml


def runs_of(folder):
    return sorted(glob.glob(os.path.join(folder, "run-*")))


def follower_desired(folder):
    """{follower name: desired offset to its first neighbour} from the folder's scenario."""
    with open(os.path.join(folder, "scenario.yaml")) as f:
        sc = yaml.safe_load(f)
    out = {}
    for v in sc.get("vehicles", []):
        if v.get("role") == "follower" and v.get("neighbours"):
            out[v["name"]] = float(v["neighbours"][0]["desired"][2])
    return out


def vertical_error(run_dir, name, dz, window):
    errs = []
    with open(os.path.join(run_dir, name + ".csv")) as f:
        for row in csv.DictReader(f):
            t = float(row["t"])
            if not (window[0] <= t < window[1]):
                continue
            z = float(row["rel0_z"])
            if math.isfinite(z):
                errs.append(abs(z - dz))
    return sum(errs) / len(errs) if errs else float("nan")


def row(folder):
    with open(os.path.join(folder, "summary.json")) as f:
        top = json.load(f)
    desired = follower_desired(folder)
    steady, mean, mx, vert = [], [], [], []
    for r in runs_of(folder):
        with open(os.path.join(r, "summary.json")) as f:
            s = json.load(f)
        steady.append(s["steady_state_formation_error_m"])
        mean.append(s["mean_formation_error_m"])
        mx.append(s["max_formation_error_m"])
        worst = float("nan")
        for name, dz in desired.items():
            window = s.get("vehicles", {}).get(name, {}).get("formation_window_s",
                                                           s["formation_window_s"])
            e = vertical_error(r, name, dz, window)
            worst = e if not math.isfinite(worst) else max(worst, e)
        vert.append(worst)

    def cell(v):
        v = [x for x in v if x is not None and math.isfinite(x)]
        if not v:
            return "n/a"
        return f"{sum(v) / len(v):.3f} ({min(v):.3f}–{max(v):.3f})"

    # A campaign's run folder is OUT/merged (fnmpc campaign): named after its campaign folder.
    path = folder.rstrip('/')
    label = os.path.basename(path)
    if label == "merged":
        label = os.path.basename(os.path.dirname(os.path.abspath(path)))
    return (f"| {label} | {top.get('compensation', '?')} | "
            f"{len(steady)} | {cell(steady)} | {cell(mean)} | {cell(mx)} | {cell(vert)} |")


def plot(csv_path, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cols = {k: [] for k in ["t", "aero_fx", "aero_fy", "aero_fz", "est_fx", "est_fy", "est_fz"]}
    with open(csv_path) as f:
        for r in csv.DictReader(f):
            for k in cols:
                cols[k].append(float(r[k]))
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 7))
    for ax, c in zip(axes, "xyz"):
        ax.plot(cols["t"], cols["aero_f" + c], lw=0.7, label=f"true aerodynamic aero_f{c}")
        ax.plot(cols["t"], cols["est_f" + c], lw=1.2, label=f"estimated m d_{c} (est_f{c})")
        ax.set_ylabel(f"F{c} [N]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    fig.suptitle("/".join(os.path.abspath(csv_path).split(os.sep)[-3:]))
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folders", nargs="*")
    p.add_argument("--plot", nargs=2, metavar=("CSV", "PNG"))
    a = p.parse_args()
    if a.plot:
        plot(*a.plot)
    if a.folders:
        print("| run folder | compensation | runs | steady state [m] | mean [m] | max [m] | "
              "vertical, mean [m] |")
        print("|---|---|---|---|---|---|---|")
        for folder in a.folders:
            print(row(folder))
    return 0


if __name__ == "__main__":
    sys.exit(main())
