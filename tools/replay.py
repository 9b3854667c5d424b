#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Writes RUN_DIR/replay.html: the interactive 3-D replay of one run of a run folder
(docs/replay.md). The page is self-contained: the samples (base64 float32) and the bundled
three.js viewer (web/replay, built by the CMake target fnmpc_replay) are inlined, so it
opens offline from file://.
Usage: /usr/bin/python3 tools/replay.py RUN_DIR --template HTML --bundle JS [--run N]"""
import argparse
import base64
import csv
import json
import math
import os
import struct
import sys

# Per vehicle and frame, in this order (web/replay/src/replay.js reads FIELDS = 10).
COLUMNS = ["x", "y", "z", "roll", "pitch", "yaw", "err0", "err1", "formation_error"]
# Samples (frames x vehicles) kept at most; beyond, every k-th log row is used so that a
# 28-vehicle, 82 s run (1641 rows at Ts = 0.05 s) still loads whole.
MAX_SAMPLES = 60000
ERROR_SCALE_M = 0.5  # tie colour: green at 0, red at and above this formation error [m]
NO_THRUST_PHASES = {"idle", "landed"}


def number(text):
    try:
        return float(text)
    except ValueError:
        return float("nan")


def read_vehicle(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def build_data(run_dir, run_index):
    with open(os.path.join(run_dir, "summary.json")) as f:
        summary = json.load(f)
    runs = summary.get("run_summaries", [summary])
    if not 1 <= run_index <= len(runs):
        raise SystemExit(f"replay: run {run_index} not in 1..{len(runs)}")
    run = runs[run_index - 1]
    rdir = os.path.join(run_dir, run.get("dir", "."))
    names = list(run["vehicles"].keys())
    rows = {}
    for name in names:
        path = os.path.join(rdir, name + ".csv")
        if not os.path.exists(path):
            raise SystemExit(f"replay: {path} missing")
        rows[name] = read_vehicle(path)
    frames = min(len(r) for r in rows.values())
    if frames == 0:
        raise SystemExit(f"replay: {rdir} has empty logs")
    stride = max(1, math.ceil(frames * len(names) / MAX_SAMPLES))
    picked = list(range(0, frames, stride))
    if picked[-1] != frames - 1:
        picked.append(frames - 1)
    times = [number(rows[names[0]][f]["t"]) for f in picked]
    values = []
    for f in picked:
        for name in names:
            r = rows[name][f]
            values.extend(number(r.get(c, "nan")) for c in COLUMNS)
            thrust = number(r.get("cmd_thrust", "nan"))
            values.append(0.0 if r.get("phase") in NO_THRUST_PHASES or not math.isfinite(thrust)
                          else thrust)
    index = {n: i for i, n in enumerate(names)}
    vehicles = []
    for name in names:
        v = run["vehicles"][name]
        vehicles.append({"name": name, "role": v.get("role", "follower"),
                         "neighbours": [index[n] for n in v.get("neighbours", []) if n in index]})
    label = f"{run.get('scenario', summary.get('scenario', ''))} - {run.get('dir', 'run')}"
    if "seed" in run:
        label += f" (seed {run['seed']})"
    pack = lambda xs: base64.b64encode(struct.pack(f"<{len(xs)}f", *xs)).decode("ascii")
    return {
        "title": label,
        "downwash": bool(run.get("downwash", False)),
        "dt": (times[-1] - times[0]) / max(len(times) - 1, 1),
        "error_scale": ERROR_SCALE_M,
        "stride": stride,
        "vehicles": vehicles,
        "t": pack(times),
        "state": pack(values),
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_dir")
    p.add_argument("--template", required=True, help="web/replay/replay.html")
    p.add_argument("--bundle", required=True, help="replay.bundle.js of the fnmpc_replay target")
    p.add_argument("--run", type=int, default=1, help="which run of the folder (1-based)")
    p.add_argument("--out", help="output (default RUN_DIR/replay.html)")
    a = p.parse_args()
    data = build_data(a.run_dir, a.run)
    with open(a.template) as f:
        page = f.read()
    with open(a.bundle) as f:
        bundle = f.read()
    # "</" cannot appear inside a <script> element's text.
    data_json = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    page = (page.replace("/*FNMPC_ERROR_SCALE*/", f"{ERROR_SCALE_M:g}")
                .replace("/*FNMPC_WAKE*/", "on" if data["downwash"] else "off")
                .replace("/*FNMPC_REPLAY_DATA*/", data_json)
                .replace("/*FNMPC_REPLAY_BUNDLE*/", bundle.replace("</script", "<\\/script")))
    out = a.out or os.path.join(a.run_dir, "replay.html")
    with open(out, "w") as f:
        f.write(page)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
