#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Executed aarch64 instructions per control step of the benchmark closed loops, counted
under qemu-aarch64 (docs/onboard.md, "Instruction counts").

Runs the aarch64 `fnmpc bench --problem P --scenario S` under qemu-aarch64 with the logs
`in_asm` (each translated block's guest instructions, once per translation), `exec` (one
line per executed block, naming its translation) and `nochain` (no block chaining, so that
every executed block is logged). The instructions of a control step are the sizes of the
blocks executed between the calls of fnmpc_bench_step_begin and fnmpc_bench_step_end
(fnmpc/rti/benchmark_ocps.hpp), libm and libc included. --singlestep translates one
instruction per block instead (slower; every executed block is one instruction), the
check of the block-size count.

  scripts/onboard-count.py BUILD/apps/fnmpc/fnmpc [--problem L ...] [--scenario nominal ...]
      [--steps K] [--csv FILE] [--json FILE] [--singlestep]

Prints one line per problem and scenario: steps counted (step 0, the initial convergence,
left out as in `fnmpc bench`), median, p99 and maximum instructions per step.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import threading

PROBLEMS = ["L", "F2", "F6", "F2-reduced", "F6-reduced"]
SCENARIOS = ["nominal", "aggressive"]
BEGIN = b"fnmpc_bench_step_begin\n"
END = b"fnmpc_bench_step_end\n"


def percentile(values, q):
    """The same nearest-rank percentile as fnmpc::rti::benchmark::Summarize."""
    v = sorted(values)
    idx = int(math.ceil(q * len(v)) - 1)
    return v[max(0, min(idx, len(v) - 1))]


def count_log(stream, singlestep):
    """Per-step instruction counts from a qemu log stream (in_asm, exec, nochain)."""
    size_of = {}  # host address of a translated block -> its guest instructions
    pending = None  # size of the block just translated (its first exec line follows)
    in_block = False
    counting = False
    current = 0
    steps = []
    for line in stream:
        if line.startswith(b"Trace "):
            in_block = False
            # Trace 0: 0x7f0cc00a64c0 [cs_base/pc/flags/cflags] symbol
            ptr = line.split(b" ", 3)[2]
            if pending is not None:
                size_of[ptr] = pending
                pending = None
            if line.endswith(BEGIN):
                counting = True
                current = 0
            elif line.endswith(END):
                if counting:
                    steps.append(current)
                counting = False
            if counting:
                current += 1 if singlestep else size_of[ptr]
        elif line.startswith(b"IN:"):
            in_block = True
            pending = 0
        elif in_block and line.startswith(b"0x"):
            pending += 1
    return steps


def run(binary, problem, scenario, steps, singlestep):
    with tempfile.TemporaryDirectory() as tmp:
        fifo = os.path.join(tmp, "qemu.log")
        os.mkfifo(fifo)
        cmd = ["qemu-aarch64"]
        if singlestep:
            cmd.append("-singlestep")
        cmd += ["-d", "in_asm,exec,nochain", "-D", fifo, binary, "bench", "--problem", problem,
                "--scenario", scenario]
        if steps:
            cmd += ["--steps", str(steps)]
        out = {}

        def target():
            out["proc"] = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)

        t = threading.Thread(target=target)
        t.start()
        with open(fifo, "rb", buffering=1 << 20) as f:
            counts = count_log(f, singlestep)
        t.join()
        proc = out["proc"]
        if proc.returncode != 0:
            sys.exit(f"onboard-count: {' '.join(cmd)} failed:\n{proc.stderr.decode()}")
        return counts


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("binary", help="the aarch64 fnmpc executable")
    ap.add_argument("--problem", action="append", choices=PROBLEMS)
    ap.add_argument("--scenario", action="append", choices=SCENARIOS)
    ap.add_argument("--steps", type=int, default=0, help="control steps per run (default 520)")
    ap.add_argument("--singlestep", action="store_true",
                    help="one instruction per translated block (the check of the method)")
    ap.add_argument("--csv", help="write every step's count here (problem,scenario,step,insns)")
    ap.add_argument("--json", help="write the summary rows here")
    a = ap.parse_args()
    rows, per_step = [], []
    print(f"{'problem':<11} {'scenario':<10} {'steps':>5} {'med':>9} {'p99':>9} {'max':>9} "
          f"{'step0':>9}", flush=True)
    for scenario in a.scenario or SCENARIOS:
        for problem in a.problem or PROBLEMS:
            counts = run(a.binary, problem, scenario, a.steps, a.singlestep)
            if len(counts) < 2:
                sys.exit(f"onboard-count: {problem} {scenario}: {len(counts)} steps found")
            later = counts[1:]
            row = {"problem": problem, "scenario": scenario, "steps": len(later),
                   "median": percentile(later, 0.5), "p99": percentile(later, 0.99),
                   "max": max(later), "step0": counts[0]}
            rows.append(row)
            per_step += [(problem, scenario, k, c) for k, c in enumerate(counts)]
            print(f"{problem:<11} {scenario:<10} {row['steps']:>5} {row['median']:>9} "
                  f"{row['p99']:>9} {row['max']:>9} {row['step0']:>9}", flush=True)
    if a.csv:
        with open(a.csv, "w") as f:
            f.write("problem,scenario,step,instructions\n")
            for p, s, k, c in per_step:
                f.write(f"{p},{s},{k},{c}\n")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=2)


if __name__ == "__main__":
    main()
