#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Plots of a run folder written by `fnmpc run` (PNG) and one HTML page bundling them: a
headline first (verdict, failures, key figures beside the reference work's;
tools/report_headline.py), then the metrics tables.
Usage: MPLBACKEND=Agg /usr/bin/python3 tools/report.py RUN_DIR"""
import csv
import html
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from report_headline import headline_html  # noqa: E402  (beside this script)


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    cols = {}
    for key in rows[0].keys() if rows else []:
        vals = []
        for r in rows:
            try:
                vals.append(float(r[key]))
            except ValueError:
                vals.append(r[key])
        cols[key] = vals
    return cols


def num(x):
    return x if isinstance(x, float) and not math.isnan(x) else float("nan")


class IncompleteRunFolder(Exception):
    """The folder is not a whole run folder of `fnmpc run`; reported in one line."""


def check_run_folder(run_dir):
    """The summary and every vehicle's CSV with data rows, or IncompleteRunFolder."""
    path = os.path.join(run_dir, "summary.json")
    try:
        with open(path) as f:
            summary = json.load(f)
    except (OSError, ValueError) as e:
        raise IncompleteRunFolder(f"{path}: unreadable summary ({e})")
    if not isinstance(summary, dict):
        raise IncompleteRunFolder(f"{path}: not a summary (expected a JSON object)")
    if summary.get("complete") is False:
        why = summary.get("stopped") or summary.get("error") or "incomplete"
        raise IncompleteRunFolder(f"{path}: the run did not complete ({why})")
    runs = summary.get("run_summaries", [summary])
    if not runs or not all(isinstance(r, dict) and isinstance(r.get("vehicles"), dict) and r["vehicles"]
                           for r in runs):
        raise IncompleteRunFolder(f"{path}: no vehicles listed")
    for r in runs:
        rdir = os.path.join(run_dir, str(r.get("dir", ".")))
        for name in r["vehicles"]:
            csv_path = os.path.join(rdir, name + ".csv")
            try:
                with open(csv_path, newline="") as f:
                    rows = sum(1 for _ in f)
            except OSError as e:
                raise IncompleteRunFolder(f"{csv_path}: {e.strerror}")
            if rows < 2:
                raise IncompleteRunFolder(f"{csv_path}: no data rows")
    return summary


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    run_dir = sys.argv[1]
    try:
        summary = check_run_folder(run_dir)
    except IncompleteRunFolder as e:
        print(f"report.py: {e}", file=sys.stderr)
        return 1
    runs = summary.get("run_summaries", [summary])
    data = []  # per run: {vehicle: columns}
    for r in runs:
        rdir = os.path.join(run_dir, r.get("dir", "."))
        vehicles = {}
        for name in r["vehicles"]:
            path = os.path.join(rdir, name + ".csv")
            if os.path.exists(path):
                vehicles[name] = read_csv(path)
        data.append(vehicles)
    names = list(runs[0]["vehicles"].keys())
    followers = [n for n in names if runs[0]["vehicles"][n]["role"] == "follower"]
    ts = summary.get("sample_time_s", 0.05)
    images = []

    # 3-D trajectories (first run).
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    for name, c in data[0].items():
        ax.plot(c["x"], c["y"], c["z"], label=name)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title("Trajectories (run 1, truth)")
    ax.legend()
    images.append(("trajectories_3d.png", "3-D trajectories of all vehicles, run 1"))
    fig.savefig(os.path.join(run_dir, images[-1][0]), dpi=110)
    plt.close(fig)

    # Formation errors, cost and KKT over time, all runs (per follower: none in a single-vehicle
    # scenario).
    per_follower = (("formation_errors", "err", False), ("cost", "cost", True), ("kkt", "kkt", True))
    for what, col, log in per_follower if followers else ():
        fig, axes = plt.subplots(len(followers), 1, figsize=(9, 3.2 * len(followers)), squeeze=False)
        for ax, name in zip(axes[:, 0], followers):
            nbs = runs[0]["vehicles"][name].get("neighbours", [])  # order of err0, err1
            for k, run in enumerate(data):
                c = run.get(name)
                if c is None:
                    continue
                if col == "err":
                    for j, nb in enumerate(nbs):
                        ax.plot(c["t"], [num(v) for v in c["err%d" % j]], lw=0.8, color="C%d" % j,
                                alpha=0.6, label="to %s" % nb if k == 0 else None)
                else:
                    ax.plot(c["t"], [num(v) for v in c[col]], lw=0.8, color="C0", alpha=0.5,
                            label="runs" if k == 0 else None)
            if log:
                ax.set_yscale("log")
            ax.set_ylabel({"err": "|dx - d| [m]", "cost": "NMPC cost", "kkt": "KKT"}[col])
            ax.set_title("%s: %s (%d runs)" % (name, what.replace("_", " "), len(data)))
            ax.axvspan(summary.get("formation_window_s", [0, 0])[0], summary.get("formation_window_s", [0, 0])[1],
                       color="g", alpha=0.05, label="formation window" if col == "err" else None)
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper right")
        axes[-1, 0].set_xlabel("t [s]")
        fig.tight_layout()
        images.append((what + ".png", what.replace("_", " ") + " over time, all runs, every follower"))
        fig.savefig(os.path.join(run_dir, images[-1][0]), dpi=110)
        plt.close(fig)

    # Solver time.
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.8))
    all_times = []
    for k, run in enumerate(data):
        for j, (name, c) in enumerate(run.items()):
            t = [num(v) * 1e3 for v in c["solver_time"]]
            all_times += [v for v in t if not math.isnan(v)]
            a1.plot(c["t"], t, ".", ms=1.5, color="C%d" % j, label=name if k == 0 else None)
    a1.axhline(ts * 1e3, color="r", ls="--", label="Ts")
    a1.set_yscale("log")
    a1.set_xlabel("t [s]")
    a1.set_ylabel("solver wall time [ms]")
    a1.legend()
    a1.grid(True, alpha=0.3)
    if all_times:
        a2.hist(all_times, bins=60, log=True)
    a2.axvline(ts * 1e3, color="r", ls="--")
    a2.set_xlabel("solver wall time per step [ms]")
    a2.set_ylabel("steps")
    fig.tight_layout()
    images.append(("solver_time.png", "NMPC solver time per step (all vehicles, all runs); red: Ts"))
    fig.savefig(os.path.join(run_dir, images[-1][0]), dpi=110)
    plt.close(fig)

    # HTML page.
    def fmt(v):
        if isinstance(v, float):
            return "%.4g" % v
        return html.escape(str(v))

    top = [(k, v) for k, v in summary.items() if not isinstance(v, (dict, list))]
    out = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>fnmpc report: %s</title>"
           "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
           "td,th{border:1px solid #ccc;padding:2px 6px}table{border-collapse:collapse}</style>"
           "</head><body>" % html.escape(str(summary.get("scenario")))]
    out.append("<h1>Scenario %s</h1>" % html.escape(str(summary.get("scenario"))))
    out.append("<p><a href='replay.html'>Interactive 3-D replay</a> (replay.html, written by "
               "<code>fnmpc report</code> after these plots)</p>")
    # What a person reads first: verdict, failures, key figures beside the reference work's.
    out.append(headline_html(summary))
    out.append("<h2>Metrics</h2><table>")
    for k, v in top:
        out.append("<tr><th align=left>%s</th><td>%s</td></tr>" % (html.escape(k), fmt(v)))
    out.append("</table>")
    keys = ["seed", "steady_state_formation_error_m", "mean_formation_error_m", "max_formation_error_m",
            "solver_time_median_s", "solver_time_max_s", "fallbacks", "recoveries", "failsafes",
            "min_separation_m", "landed_safely"]
    out.append("<h2>Runs</h2><table><tr>%s</tr>" % "".join("<th>%s</th>" % k for k in keys))
    for r in runs:
        out.append("<tr>%s</tr>" % "".join("<td>%s</td>" % fmt(r.get(k)) for k in keys))
    out.append("</table><h2>Per vehicle (run 1)</h2><table>")
    vkeys = sorted({k for v in runs[0]["vehicles"].values() for k, x in v.items() if not isinstance(x, dict)})
    out.append("<tr><th></th>%s</tr>" % "".join("<th>%s</th>" % n for n in names))
    for k in vkeys:
        out.append("<tr><th align=left>%s</th>%s</tr>" % (k, "".join(
            "<td>%s</td>" % fmt(runs[0]["vehicles"][n].get(k, "")) for n in names)))
    out.append("</table>")
    for img, caption in images:
        out.append("<h3>%s</h3><img src='%s' style='max-width:100%%'>" % (html.escape(caption), img))
    out.append("</body></html>")
    path = os.path.join(run_dir, "report.html")
    with open(path, "w") as f:
        f.write("\n".join(out))
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
