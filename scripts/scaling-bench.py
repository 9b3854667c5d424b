#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Scaling benchmark of the whole closed loop (docs/benchmarks.md "Scaling"): real-time factor
and peak resident memory of `fnmpc run` for growing generated formations.

  scripts/scaling-bench.py [--fnmpc build/apps/fnmpc/fnmpc] [--counts 2 3 10 25 50 100]
                           [--shape grid] [--duration 40] [--repeat 1] [--threads 2]

Each count flies a generated formation (`formation:` block, docs/scenarios.md) of the
given shape, 2.5 m spacing, two ties per follower, the leader on 4 s legs, for --duration
simulated seconds, one `fnmpc run` process per count with --threads threads for its vehicles'
estimators and controllers (default: every CPU; `fnmpc run --threads`). Real-time factor:
simulated time / wall time of the process; CPU: its user + system time over every thread
(less sensitive to other load on the machine than the wall time); memory: the process's peak
resident set (getrusage). Prints a Markdown table; the figures depend on the machine and its load."""
import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SCENARIO = """name: scale-{shape}-{count}
description: scaling benchmark, {count} vehicles in a generated {shape}
duration: {duration}
seed: 1
downwash: false
battery_sag: true
vehicle_file: {root}/config/vehicles/storm-drone-4.yaml
sensors_file: {root}/config/sensors/default.yaml
formation: {{shape: {shape}, count: {count}, spacing: 2.5, ties: 2}}
leader:
  mode: waypoints
  start_time: 12.0
  waypoints: [[2.0, 0.0, 0.0], [2.0, 2.0, 0.5], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0]]
  leg_duration: 4.0
  hold_duration: 4.0
phases:
  landing_time: {landing}
"""


def run(fnmpc, scenario, out, threads):
    """Wall time [s], CPU time [s], peak RSS [MiB] and exit code of one `fnmpc run`."""
    t0 = time.perf_counter()
    p = subprocess.Popen([fnmpc, "run", str(scenario), "-q", "-o", str(out),
                          "--threads", str(threads)],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    stderr = p.stderr.read()
    p.stderr.close()
    cpu = usage.ru_utime + usage.ru_stime
    return wall, cpu, usage.ru_maxrss / 1024.0, os.waitstatus_to_exitcode(status), stderr


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fnmpc", default=str(ROOT / "build/apps/fnmpc/fnmpc"))
    ap.add_argument("--counts", type=int, nargs="+", default=[2, 3, 10, 25, 50, 100])
    ap.add_argument("--shape", default="grid", choices=["wedge", "line", "grid", "circle"])
    ap.add_argument("--duration", type=float, default=40.0, help="simulated seconds (>= 30)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per count; the fastest counts")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                    help="fnmpc run --threads (default: every CPU)")
    args = ap.parse_args()
    if not Path(args.fnmpc).is_file():
        sys.exit(f"scaling-bench: {args.fnmpc}: no such executable (build it, or --fnmpc)")
    if args.duration < 30:
        sys.exit("scaling-bench: --duration must be >= 30 s (take-off, one leg, landing)")
    print(f"scaling-bench: {args.fnmpc}, {args.shape}, {args.duration:g} s simulated, "
          f"best of {args.repeat}, --threads {args.threads}, {os.cpu_count()} CPUs, "
          f"load {os.getloadavg()[0]:.1f}")
    print("| vehicles | wall [s] | real-time factor | CPU [s] | peak memory [MiB] | "
          "per vehicle [MiB] | exit |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="fnmpc-scale-") as tmp:
        for count in args.counts:
            scenario = Path(tmp) / f"scale-{count}.yaml"
            scenario.write_text(SCENARIO.format(shape=args.shape, count=count, root=ROOT,
                                                duration=args.duration,
                                                landing=args.duration - 8.0))
            best = None
            for k in range(args.repeat):
                out = Path(tmp) / f"run-{count}-{k}"
                wall, cpu, rss, code, err = run(args.fnmpc, scenario, out, args.threads)
                if code not in (0, 3):
                    sys.exit(f"scaling-bench: {count} vehicles: fnmpc run exited {code}:\n{err}")
                if best is None or wall < best[0]:
                    best = (wall, cpu, rss, code)
            wall, cpu, rss, code = best
            print(f"| {count} | {wall:.2f} | {args.duration / wall:.1f}× | {cpu:.2f} | {rss:.0f} | "
                  f"{rss / count:.2f} | {code} |", flush=True)


if __name__ == "__main__":
    main()
