#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Load time of replay.html for a large formation (docs/replay.md, "Load time"): writes a
scenario with N vehicles (a leader and rows of three followers, each follower tied to two
vehicles of the row ahead, 2.5 m apart) on the triangle's vehicle, sensors and waypoints,
flies it with `fnmpc run`, writes the replay with `fnmpc report --replay-only` and opens it
in headless Chromium (tests/replay/devtools.py) several times. Prints the page size and the
time from navigation start to the viewer's ready state (data decoded, scene built, first
frame drawn) of each load.
Usage: /usr/bin/python3 studies/replay-load-time/replay_load_time.py FNMPC_EXE [--vehicles 28] [--loads 5]"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "replay"))
from devtools import Browser  # noqa: E402

SPACING = 2.5  # m


def scenario_yaml(n):
    cfg = os.path.join(ROOT, "config")
    lines = [f"name: wedge{n}", f"description: leader and {n - 1} followers in rows of three",
             "duration: 82.0", "seed: 1", "downwash: false", "battery_sag: true",
             f"vehicle_file: {cfg}/vehicles/storm-drone-4.yaml",
             f"sensors_file: {cfg}/sensors/default.yaml", "vehicles:",
             "  - {name: v00, role: leader, start: [0.0, 0.0]}"]
    starts = {"v00": (0.0, 0.0)}
    rows = [["v00"]]
    i = 1
    while i < n:
        row = []
        for col in range(3):
            if i >= n:
                break
            name = f"v{i:02d}"
            starts[name] = (-SPACING * len(rows), SPACING * (col - 1))
            row.append(name)
            i += 1
        rows.append(row)
    for r, row in enumerate(rows[1:], start=1):
        for c, name in enumerate(row):
            ahead = rows[r - 1]
            if len(ahead) == 1:  # behind the leader: the leader and a row-mate
                nbs = [ahead[0], row[c - 1] if c > 0 else row[min(1, len(row) - 1)]]
            else:
                nbs = [ahead[min(c, len(ahead) - 1)], ahead[(c + 1) % len(ahead)]]
            nbs = list(dict.fromkeys(n for n in nbs if n != name))
            x, y = starts[name]
            lines += [f"  - name: {name}", "    role: follower", f"    start: [{x}, {y}]",
                      "    frame: m", "    neighbours:"]
            for nb in nbs:
                dx, dy = starts[nb][0] - x, starts[nb][1] - y
                lines.append(f"      - {{vehicle: {nb}, desired: [{dx}, {dy}, 0.0]}}")
    lines += ["leader:", "  mode: waypoints", "  start_time: 12.0", "  waypoints:",
              "    - [1.5, 0.0, 0.5]", "    - [1.5, 1.5, 0.0]", "    - [0.0, 1.5, 0.5]",
              "    - [-1.0, 0.75, 0.25]", "    - [-1.0, -0.5, 0.0]", "    - [0.0, 0.0, 0.0]"]
    return "\n".join(lines) + "\n"


def main():
    p = argparse.ArgumentParser()
    p.add_argument("fnmpc")
    p.add_argument("--vehicles", type=int, default=28)
    p.add_argument("--loads", type=int, default=5)
    p.add_argument("--keep", help="work folder to keep (default: a temporary one)")
    a = p.parse_args()
    work = a.keep or tempfile.mkdtemp(prefix="fnmpc-replay-load-")
    os.makedirs(work, exist_ok=True)
    try:
        scenario = os.path.join(work, "scenario.yaml")
        with open(scenario, "w") as f:
            f.write(scenario_yaml(a.vehicles))
        run_dir = os.path.join(work, "run")
        if not os.path.exists(os.path.join(run_dir, "summary.json")):
            subprocess.run([a.fnmpc, "run", scenario, "-q", "-o", run_dir], check=True)
        subprocess.run([a.fnmpc, "report", run_dir, "--replay-only"], check=True,
                       stdout=subprocess.DEVNULL)
        page = os.path.join(run_dir, "replay.html")
        times = []
        for _ in range(a.loads):
            b = Browser()
            try:
                b.call("Page.navigate", url="file://" + page)
                status = b.wait_for("document.body && document.body.dataset.status !== 'loading'"
                                    " && document.body.dataset.status", timeout=60)
                if status != "ready":
                    raise SystemExit(f"replay failed: {status}")
                times.append(b.evaluate("fnmpcReplay.readyMs") / 1000.0)
                frames = b.evaluate("fnmpcReplay.frames")
                errors = b.errors()
            finally:
                b.close()
            if errors:
                raise SystemExit(f"console errors: {errors[:3]}")
        print(f"vehicles {a.vehicles}, frames {frames}, replay.html "
              f"{os.path.getsize(page) / 1e6:.1f} MB")
        print("load to ready [s]: " + ", ".join(f"{t:.2f}" for t in times) +
              f"; median {statistics.median(times):.2f}, max {max(times):.2f}")
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
