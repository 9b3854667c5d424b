#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""The attitude model choice of `fnmpc sysid` does not flip across resamplings of one
campaign's attitude steps (docs/sysid.md, "Model selection").

usage: model_choice_stability_test.py FNMPC CAMPAIGN_DIR [--synth-delay D]

CAMPAIGN_DIR holds campaign.yaml and attitude_steps.csv (read in place, not copied); with
--synth-delay the campaign is first written by `fnmpc sysid synth --delay D` into a
temporary folder. Variants of attitude_steps.csv, each run through `fnmpc sysid`:
  original; odd rows; even rows (half the logging rate, every step kept); first half and
  second half of the record (half the steps each); three block bootstraps (5 s blocks drawn
  with replacement, seeds 1-3, joined with a 1 s gap in the time stamps so the joins are
  gaps, detected and left out of the fits). A synthetic campaign (one step per sign and
  axis, one axis after the other) has no halves or blocks with every axis stepped: its
  variants are the odd and even rows and two more noise realisations (synth --seed 8, 9).
Per axis, the written model (first order + transport delay, or lag + delay - PD delay: the
PD decision and the conservative undecided case write the same kind of tau) must be the
same in every variant that has steps on that axis (a half of a campaign that steps the axes
one after the other may have none; the original must have them), and the original run must
exit 0. Prints one row per variant.
"""
import csv
import concurrent.futures
import json
import os
import random
import subprocess
import sys
import tempfile

AXES = ("roll", "pitch", "yaw")


def read_rows(path):
    with open(path, newline="") as f:
        r = csv.reader(f)
        header = next(r)
        return header, [row for row in r]


def write_rows(path, header, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)


def bootstrap(rows, seed, block=5.0, gap=1.0):
    t = [float(r[0]) for r in rows]
    t0, t1 = t[0], t[-1]
    blocks = []
    start = t0
    while start < t1:
        blocks.append([r for r, ti in zip(rows, t) if start <= ti < start + block])
        start += block
    blocks = [b for b in blocks if len(b) > 10]
    rng = random.Random(seed)
    out, now = [], 0.0
    for _ in range(len(blocks)):
        b = rng.choice(blocks)
        b0 = float(b[0][0])
        for r in b:
            out.append([f"{now + float(r[0]) - b0:.6f}"] + r[1:])
        now = float(out[-1][0]) + gap
    return out


def campaign_with(src_yaml, steps_path, out_yaml):
    """The campaign file with attitude_steps pointing at steps_path; the other relative
    paths made absolute against the source campaign's folder."""
    base = os.path.dirname(os.path.abspath(src_yaml))
    lines = []
    for line in open(src_yaml):
        key, sep, value = line.partition(":")
        v = value.strip()
        if key.strip() == "attitude_steps":
            line = f"attitude_steps: {steps_path}\n"
        elif sep and v.endswith(".csv") and not v.startswith("/"):
            line = f"{key}: {os.path.join(base, v)}\n"
        elif "runs:" in line:
            for name in ("pendulum_x.csv", "pendulum_y.csv", "pendulum_z.csv"):
                line = line.replace(f" {name}", f" {os.path.join(base, name)}")
        lines.append(line)
    with open(out_yaml, "w") as f:
        f.writelines(lines)


def kind(model):
    if model.startswith("first order"):
        return "first order + transport delay"
    return "lag + delay - PD delay"


def main():
    args = sys.argv[1:]
    delay = None
    if "--synth-delay" in args:
        i = args.index("--synth-delay")
        delay = args[i + 1]
        del args[i:i + 2]
    if len(args) != 2:
        print(__doc__)
        return 2
    fnmpc, cdir = args
    work = tempfile.mkdtemp(prefix="fnmpc-choice-")
    if delay is not None:
        cdir = os.path.join(work, "synth")
        subprocess.run([fnmpc, "sysid", "synth", cdir, "--delay", delay], check=True,
                       stdout=subprocess.DEVNULL)
    src_yaml = os.path.join(cdir, "campaign.yaml")
    header, rows = read_rows(os.path.join(cdir, "attitude_steps.csv"))
    half = float(rows[0][0]) + 0.5 * (float(rows[-1][0]) - float(rows[0][0]))
    variants = {
        "original": rows,
        "odd rows": rows[1::2],
        "even rows": rows[0::2],
        "first half": [r for r in rows if float(r[0]) < half],
        "second half": [r for r in rows if float(r[0]) >= half],
    }
    extra = {}  # variant name -> campaign folder of its own
    if delay is None:
        for seed in (1, 2, 3):
            variants[f"block bootstrap {seed}"] = bootstrap(rows, seed)
    else:
        # The synthetic campaign steps each axis once per sign, one axis after the other:
        # its halves and blocks lack steps. Its resamplings are new noise realisations.
        del variants["first half"], variants["second half"]
        for seed in (8, 9):
            d = os.path.join(work, f"synth_seed{seed}")
            subprocess.run([fnmpc, "sysid", "synth", d, "--delay", delay, "--seed", str(seed)],
                           check=True, stdout=subprocess.DEVNULL)
            extra[f"noise seed {seed}"] = d
            variants[f"noise seed {seed}"] = read_rows(os.path.join(d, "attitude_steps.csv"))[1]
    choices = {a: {} for a in AXES}
    failed = False
    jobs = {}
    for name, vrows in variants.items():
        tag = name.replace(" ", "_")
        steps = os.path.join(work, f"steps_{tag}.csv")
        write_rows(steps, header, vrows)
        yaml = os.path.join(work, f"campaign_{tag}.yaml")
        campaign_with(os.path.join(extra[name], "campaign.yaml") if name in extra else src_yaml,
                      steps, yaml)
        jobs[name] = (yaml, os.path.join(work, f"vehicle_{tag}.yaml"))
    # Two identifications at a time (each is one thread): the variants are independent.
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        results = dict(zip(jobs, pool.map(
            lambda job: subprocess.run([fnmpc, "sysid", job[0], "-o", job[1], "--no-plots"],
                                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                       text=True),
            jobs.values())))
    for name in variants:
        out = jobs[name][1]
        r = results[name]
        with open(out + ".report/summary.json") as f:
            s = json.load(f)
        row = [f"{name:<18} exit {r.returncode}"]
        for a in AXES:
            at = s.get("attitude", {}).get(a, {})
            if "validation" not in at:
                # A variant without steps on this axis (a half of a campaign that steps the
                # axes one after the other): nothing to choose, not counted.
                row.append(f"{a}: not identified (no steps in this variant)")
                continue
            val = at["validation"]
            choices[a][name] = kind(at["delay_model"])
            row.append(f"{a}: {choices[a][name][:11]:<11} tau {at['vehicle_time_constant']:.4f} "
                       f"margin {100 * val['margin']:+6.1f} % (folds "
                       f"{100 * val['fold_margins'][0]:+.1f}, {100 * val['fold_margins'][1]:+.1f})")
        print(" | ".join(row))
        if name == "original" and r.returncode != 0:
            print(f"FAIL: the original campaign exits {r.returncode}:\n{r.stderr}")
            failed = True
    for a in AXES:
        if "original" not in choices[a]:
            print(f"FAIL: {a}: not identified on the original campaign")
            failed = True
            continue
        kinds = set(choices[a].values())
        if len(kinds) != 1:
            print(f"FAIL: {a}: the written model flips across variants: {choices[a]}")
            failed = True
        else:
            print(f"{a}: {kinds.pop()} in all {len(choices[a])} variants with {a} steps")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
