#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Scaling benchmark of the whole closed loop (docs/benchmarks.md "Scaling"): real-time factor
and peak resident memory of `fnmpc run` for growing generated formations.

  scripts/scaling-bench.py [--fnmpc build/apps/fnmpc/fnmpc] [--counts 2 3 10 25 50 100]
                           [--shape grid] [--duration 40] [--repeat 1] [--threads 2]
                           [--reality both] [--profile]

Each count flies a generated formation (`formation:` block, docs/scenarios.md) of the
given shape, 2.5 m spacing, two ties per follower, the leader on 4 s legs, for --duration
simulated seconds, one `fnmpc run` process per count with --threads threads for its vehicles'
estimators and controllers (default: every CPU; `fnmpc run --threads`). Real-time factor:
simulated time / wall time of the process; CPU: its user + system time over every thread
(less sensitive to other load on the machine than the wall time); memory: the process's peak
resident set (getrusage). --reality: the plant (`fnmpc run --reality`), `both` flies each
count with the ideal plant and with reality on, side by side with the ratio of their CPU time.
--profile: each run under `perf record` (Debian's perf), and the share of its samples in the
world (MuJoCo, fnmpc::sim), the estimators (fnmpc::estimation) and the NMPC (fnmpc::rti, ocp,
qp, formation, model); the rest (Eigen kernels inlined into no named function, libm, libc, the
runner) is "other". Prints a Markdown table; the figures depend on the machine and its load."""
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


SHARES = (("world", ("libmujoco", "fnmpc::sim")),
          ("estimators", ("fnmpc::estimation",)),
          ("NMPC", ("fnmpc::rti", "fnmpc::ocp", "fnmpc::qp", "fnmpc::formation", "fnmpc::model")))


def shares(perf_data):
    """Percent of the samples of a perf recording per SHARES group, and the rest."""
    text = subprocess.run(["perf", "report", "-i", str(perf_data), "--stdio", "--no-children",
                           "--sort", "dso,sym"], capture_output=True, text=True).stdout
    out = {name: 0.0 for name, _ in SHARES}
    total = 0.0
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#") or "%" not in line.split()[0]:
            continue
        pct = float(line.split()[0].rstrip("%"))
        total += pct
        for name, keys in SHARES:
            if any(k in line for k in keys):
                out[name] += pct
                break
    out["other"] = max(0.0, total - sum(out.values()))
    return out


def run(fnmpc, scenario, out, threads, reality, profile):
    """Wall time [s], CPU time [s], peak RSS [MiB], exit code, stderr and the perf shares (or
    None) of one `fnmpc run`."""
    cmd = [fnmpc, "run", str(scenario), "-q", "-o", str(out), "--threads", str(threads),
           "--reality", reality]
    if profile:
        cmd = ["perf", "record", "-q", "-F", "499", "-o", str(out) + ".perf", "--"] + cmd
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    stderr = p.stderr.read()
    p.stderr.close()
    cpu = usage.ru_utime + usage.ru_stime
    share = shares(str(out) + ".perf") if profile else None
    return wall, cpu, usage.ru_maxrss / 1024.0, os.waitstatus_to_exitcode(status), stderr, share


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fnmpc", default=str(ROOT / "build/apps/fnmpc/fnmpc"))
    ap.add_argument("--counts", type=int, nargs="+", default=[2, 3, 10, 25, 50, 100])
    ap.add_argument("--shape", default="grid", choices=["wedge", "line", "grid", "circle"])
    ap.add_argument("--duration", type=float, default=40.0, help="simulated seconds (>= 30)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per count; the fastest counts")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1,
                    help="fnmpc run --threads (default: every CPU)")
    ap.add_argument("--reality", default="both", choices=["on", "off", "both"],
                    help="the plant: fnmpc run --reality; both: off and on side by side")
    ap.add_argument("--profile", action="store_true",
                    help="run under perf record and report the world / estimators / NMPC shares")
    args = ap.parse_args()
    if not Path(args.fnmpc).is_file():
        sys.exit(f"scaling-bench: {args.fnmpc}: no such executable (build it, or --fnmpc)")
    if args.duration < 30:
        sys.exit("scaling-bench: --duration must be >= 30 s (take-off, one leg, landing)")
    plants = ["off", "on"] if args.reality == "both" else [args.reality]
    print(f"scaling-bench: {args.fnmpc}, {args.shape}, {args.duration:g} s simulated, "
          f"best of {args.repeat}, --threads {args.threads}, {os.cpu_count()} CPUs, "
          f"load {os.getloadavg()[0]:.1f}")
    print("| vehicles | reality | wall [s] | real-time factor | CPU s per simulated s | "
          "CPU on / off | peak memory [MiB] | world / estimators / NMPC / other [%] | exit |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="fnmpc-scale-") as tmp:
        for count in args.counts:
            scenario = Path(tmp) / f"scale-{count}.yaml"
            scenario.write_text(SCENARIO.format(shape=args.shape, count=count, root=ROOT,
                                                duration=args.duration,
                                                landing=args.duration - 8.0))
            cpu_off = None
            for plant in plants:
                best = None
                for k in range(args.repeat):
                    out = Path(tmp) / f"run-{count}-{plant}-{k}"
                    wall, cpu, rss, code, err, share = run(args.fnmpc, scenario, out,
                                                           args.threads, plant, args.profile)
                    if code not in (0, 3):
                        sys.exit(f"scaling-bench: {count} vehicles, reality {plant}: fnmpc run "
                                 f"exited {code}:\n{err}")
                    if best is None or wall < best[0]:
                        best = (wall, cpu, rss, code, share)
                wall, cpu, rss, code, share = best
                if plant == "off":
                    cpu_off = cpu
                ratio = f"{cpu / cpu_off:.2f}" if plant == "on" and cpu_off else "—"
                split = (" / ".join(f"{share[x]:.0f}" for x in ("world", "estimators", "NMPC",
                                                                 "other")) if share else "—")
                print(f"| {count} | {plant} | {wall:.2f} | {args.duration / wall:.1f}× | "
                      f"{cpu / args.duration:.3f} | {ratio} | {rss:.0f} | {split} | {code} |",
                      flush=True)


if __name__ == "__main__":
    main()
