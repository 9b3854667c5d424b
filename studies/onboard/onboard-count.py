#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Executed aarch64 instructions per control step of the benchmark closed loops, counted
under qemu-aarch64 (docs/onboard.md, "Instruction counts").

Runs the aarch64 `fnmpc bench --problem P --scenario S` under qemu-aarch64 with the logs
`in_asm` (each translated block's guest instructions, once per translation), `exec` (one
line per executed block, naming its translation) and `nochain` (no block chaining, so that
every executed block is logged). The instructions of a control step are the sizes of the
blocks executed between the calls of fnmpc_bench_step_begin and fnmpc_bench_step_end
(bench/ocp_spec/benchmark_ocps.hpp), libm and libc included. --singlestep translates one
instruction per block instead (slower; every executed block is one instruction), the
check of the block-size count.

  studies/onboard/onboard-count.py BUILD/apps/fnmpc/fnmpc [--problem L ...] [--scenario nominal ...]
      [--steps K] [--csv FILE] [--json FILE] [--singlestep] [--fit-active-set REFERENCE]
  studies/onboard/onboard-count.py --from-csv FILE [--problem ...] --fit-active-set REFERENCE

Prints one line per problem and scenario: steps counted (step 0, the initial convergence,
left out as in `fnmpc bench`), median, p99 and maximum instructions per step.
--fit-active-set joins the counts with the QP active-set changes of the steps sampled in
REFERENCE (tests/onboard/cross_arch_reference.csv, equal on aarch64: cross_arch_test) and
prints the least-squares line instructions = a + b * changes; --from-csv summarises the
counts a previous --csv run wrote instead of running qemu.
"""
import argparse
import csv
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
    """The same nearest-rank percentile as fnmpc::bench::Summarize."""
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


def fit_active_set(reference, per_step):
    """Least-squares line of instructions against QP active-set changes, per problem and
    scenario, over the steps (after step 0) that both the counts and REFERENCE hold."""
    changes = {}
    with open(reference) as f:
        for r in csv.DictReader(f):
            changes[(r["problem"], r["scenario"], int(r["step"]))] = int(r["qp_iterations"])
    groups = {}
    for p, s, k, c in per_step:
        if k > 0 and (p, s, k) in changes:
            groups.setdefault((p, s), []).append((changes[(p, s, k)], c))
    for (p, s), pts in groups.items():
        n = len(pts)
        mx = sum(x for x, _ in pts) / n
        my = sum(y for _, y in pts) / n
        sxx = sum((x - mx) ** 2 for x, _ in pts)
        worst = max(pts, key=lambda t: t[1])
        lo, hi = min(x for x, _ in pts), max(x for x, _ in pts)
        if sxx == 0:
            print(f"fit {p} {s}: {n} sampled steps, all with {lo} active-set changes: no line "
                  f"(every step {my:.0f} instructions on average)")
            continue
        b = sum((x - mx) * (y - my) for x, y in pts) / sxx
        print(f"fit {p} {s}: {n} sampled steps, {lo}..{hi} active-set changes: "
              f"{my - b * mx:.0f} + {b:.0f} per change; largest sampled count {worst[1]} "
              f"at {worst[0]} changes")


def read_counts(path):
    """The per-step counts a --csv run wrote: {(problem, scenario): [(step, count), ...]}."""
    steps = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            steps.setdefault((r["problem"], r["scenario"]), []).append(
                (int(r["step"]), int(r["instructions"])))
    return {key: sorted(v) for key, v in steps.items()}


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
    ap.add_argument("binary", nargs="?", help="the aarch64 fnmpc executable")
    ap.add_argument("--problem", action="append", choices=PROBLEMS)
    ap.add_argument("--scenario", action="append", choices=SCENARIOS)
    ap.add_argument("--steps", type=int, default=0, help="control steps per run (default 520)")
    ap.add_argument("--singlestep", action="store_true",
                    help="one instruction per translated block (the check of the method)")
    ap.add_argument("--csv", help="write every step's count here (problem,scenario,step,instructions)")
    ap.add_argument("--json", help="write the summary rows here")
    ap.add_argument("--fit-active-set", metavar="REFERENCE",
                    help="fit instructions against the QP active-set changes of REFERENCE")
    ap.add_argument("--from-csv", metavar="FILE", help="read the counts of a --csv run")
    a = ap.parse_args()
    if (a.binary is None) == (a.from_csv is None):
        ap.error("give either the aarch64 fnmpc executable or --from-csv FILE")
    problems, scenarios = a.problem or PROBLEMS, a.scenario or SCENARIOS
    if a.from_csv:
        recorded = read_counts(a.from_csv)
        wanted = [(p, s) for s in scenarios for p in problems if (p, s) in recorded]
        if not wanted:
            sys.exit(f"onboard-count: {a.from_csv}: no counts of the problems and scenarios asked for")
        counts_of = lambda p, s: recorded[(p, s)]
    else:
        wanted = [(p, s) for s in scenarios for p in problems]
        counts_of = lambda p, s: list(enumerate(run(a.binary, p, s, a.steps, a.singlestep)))
    rows, per_step = [], []
    print(f"{'problem':<11} {'scenario':<10} {'steps':>5} {'med':>9} {'p99':>9} {'max':>9} "
          f"{'step0':>9}", flush=True)
    for problem, scenario in wanted:
        counts = counts_of(problem, scenario)  # (step, instructions)
        later = [c for k, c in counts if k > 0]
        if not later:
            sys.exit(f"onboard-count: {problem} {scenario}: no step after step 0 found")
        row = {"problem": problem, "scenario": scenario, "steps": len(later),
               "median": percentile(later, 0.5), "p99": percentile(later, 0.99),
               "max": max(later), "step0": next((c for k, c in counts if k == 0), "-")}
        rows.append(row)
        per_step += [(problem, scenario, k, c) for k, c in counts]
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
    if a.fit_active_set:
        fit_active_set(a.fit_active_set, per_step)


if __name__ == "__main__":
    main()
