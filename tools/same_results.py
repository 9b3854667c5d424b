#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Results of one fnmpc binary, to check that a refactor changes no result.

  /usr/bin/python3 tools/same_results.py record FNMPC OUT_DIR [--quick]
  /usr/bin/python3 tools/same_results.py compare DIR_A DIR_B

`record` flies every shipped scenario under config/scenarios/ (top level and stress/; not
scale/, minutes each), a 12-run slice of the fault campaign
(studies/faults-and-safety/fault-campaign.py --runs 12 --keep), the `fnmpc bench` closed
loops (--json) and a sysid round trip (`sysid synth` then `sysid` and `calibrate`), writing
each into OUT_DIR. --quick flies only
triangle, stress/kill-follower and the bench.

`compare` walks DIR_A and reports every file that differs from DIR_B, ignoring what is
wall-clock by nature: CSV columns named solver_time, JSON keys containing solver_time,
over_budget, wall, elapsed, _us or _ms (bench timings), manifests (hashes of CSVs with
solver times), report images/HTML, and the recorded folder's own path. Exits 1 on any difference.
"""
import csv
import glob
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WALL_KEYS = ("solver_time", "over_budget", "wall", "elapsed", "_us", "_ms")
SKIP_EXT = (".png", ".html", ".svg", ".log", ".fnmpc-manifest")


def run(cmd, **kw):
    print("  $", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, **kw)


def record(fnmpc, out, quick):
    os.makedirs(out, exist_ok=True)
    scen = sorted(glob.glob(os.path.join(ROOT, "config/scenarios/*.yaml"))
                  + glob.glob(os.path.join(ROOT, "config/scenarios/stress/*.yaml")))
    if quick:
        scen = [s for s in scen if s.endswith(("/triangle.yaml", "stress/kill-follower.yaml"))]
    for s in scen:
        name = os.path.relpath(s, os.path.join(ROOT, "config/scenarios")).replace("/", "_")[:-5]
        run([fnmpc, "run", s, "-q", "-o", os.path.join(out, "run_" + name), "--overwrite"])
    with open(os.path.join(out, "bench.json"), "w") as f:
        print("  $", fnmpc, "bench --json", flush=True)
        subprocess.run([fnmpc, "bench", "--json"], stdout=f, stderr=subprocess.DEVNULL)
    if quick:
        return
    run(["/usr/bin/python3", os.path.join(ROOT, "studies/faults-and-safety/fault-campaign.py"),
         "--fnmpc", fnmpc, "--runs", "12", "--keep", "--out", os.path.join(out, "faults")])
    synth = os.path.join(out, "sysid")
    run([fnmpc, "sysid", "synth", synth])
    run([fnmpc, "sysid", os.path.join(synth, "campaign.yaml"), "-o",
         os.path.join(out, "sysid_vehicle.yaml"), "--no-plots"])


def strip_json(v):
    if isinstance(v, dict):
        return {k: strip_json(x) for k, x in v.items()
                if not any(w in k for w in WALL_KEYS)}
    if isinstance(v, list):
        return [strip_json(x) for x in v]
    return v


def load(path, root):
    """The file's comparable content; root (the recorded folder) is replaced by "<root>"."""
    if path.endswith(".json"):
        try:
            with open(path) as f:
                return strip_json(json.loads(f.read().replace(root, "<root>")))
        except ValueError:
            pass
    if path.endswith(".csv"):
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
        if rows:
            keep = [i for i, h in enumerate(rows[0]) if "solver_time" not in h]
            return [[r[i] for i in keep if i < len(r)] for r in rows]
        return rows
    with open(path, "rb") as f:
        return f.read().replace(root.encode(), b"<root>")


def compare(a, b):
    bad = 0
    seen = 0
    for d, _, files in os.walk(a):
        for name in files:
            if name.endswith(SKIP_EXT):
                continue
            pa = os.path.join(d, name)
            pb = os.path.join(b, os.path.relpath(pa, a))
            seen += 1
            if not os.path.exists(pb):
                print("missing in B:", os.path.relpath(pa, a))
                bad += 1
            elif load(pa, os.path.abspath(a)) != load(pb, os.path.abspath(b)):
                print("differs:", os.path.relpath(pa, a))
                bad += 1
    print(f"{seen} files compared, {bad} differ")
    return 1 if bad or not seen else 0


def main():
    args = sys.argv[1:]
    if len(args) >= 3 and args[0] == "record":
        record(os.path.abspath(args[1]), os.path.abspath(args[2]), "--quick" in args)
        return 0
    if len(args) == 3 and args[0] == "compare":
        return compare(args[1], args[2])
    print(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main())
