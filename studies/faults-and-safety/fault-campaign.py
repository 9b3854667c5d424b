#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Fault campaign: randomized fault runs of the triangle with `fnmpc run`, table per fault kind.

  /usr/bin/python3 studies/faults-and-safety/fault-campaign.py [--fnmpc build/apps/fnmpc/fnmpc] [--runs 210]
      [--seed 1] [--duration 30] [--out DIR] [--keep] [--only 55 198]

A seeded RNG (--seed) draws, per run, one fault kind (round robin over KINDS, so every kind
gets the same share) and its parameters: vehicle, time inside the NMPC flight, dropout windows,
rates and sizes, and the run's noise seed. Each variant is the triangle scenario
(config/scenarios/triangle.yaml, shortened with --duration) with a `faults:` block
(docs/scenarios.md), written to a temporary folder and flown with `fnmpc run -q`.

Per run it checks: the process exited 0, or 3 (the run finished and a vehicle failed a check
of its own, docs/failure.md: this script judges those runs by the checks below; any other exit
is a crash), no non-finite command (thrust, roll,
pitch, yaw) in any CSV row of a vehicle whose controller is alive, and every vehicle either
landed safely (summary.json `landed_safely`) or is the one the fault downed
(`faults.downed_vehicles`: kill_controller and motors_off targets), no collision in summary.json's `failures` (two true CoMs closer than
`metrics.collision_distance`, any vehicle), and no vehicle that is not
downed touched the ground in the NMPC phase (its true CoM within 1.5 cm of the resting height,
the touchdown test of `fnmpc run`, in a CSV row of phase `nmpc`: a ground strike, which
summary.json does not count as a touchdown; the speed is the true v_z of the row before). It prints the markdown
table of docs/results.md ("Faults and safety", fault campaign) and exits 1 when a run failed
a check. `--only` flies the listed run numbers alone (0-based, as printed), with the faults and
seeds they get in the whole campaign (every run is still drawn), to reproduce a failure.
"""
import argparse
import csv
import glob
import json
import math
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time

import yaml

KINDS = ["kill_controller", "motors_off", "sensor_dropouts", "outliers", "solver_failures",
         "mixed"]
SENSORS = ["mocap", "imu", "optical_flow", "compass", "battery", "relative"]
COMMAND_COLUMNS = ("cmd_thrust", "cmd_roll", "cmd_pitch", "cmd_yaw")
REST_HEIGHT = 0.1  # m, sim::World::kRestHeight: CoM height of a vehicle resting on the ground
CONTACT_MARGIN = 0.015  # m, fnmpc run's touchdown test (fnmpc/experiment/run_observers.cpp)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # studies/<section>/


def flight_window(sc, duration):
    """Times [s] in which every vehicle flies the NMPC in the shortened scenario."""
    ph = sc.get("phases", {})
    start = (ph.get("takeoff_time", 1.0) + ph.get("takeoff_height", 1.0) / ph.get("climb_speed", 0.5)
             + ph.get("hover_before_switch", 1.5) + ph.get("blend_time", 0.5) + 0.5)
    # fnmpc run --duration keeps the scenario's landing allowance (duration - landing_time):
    # the landing moves earlier by the time cut (docs/scenarios.md, "Shortened runs").
    landing = ph.get("landing_time", 50.0) - (sc.get("duration", 60.0) - duration)
    return start, landing


def draw_faults(rng, kind, names, t0, t1):
    def dropouts(n):
        out = []
        for _ in range(n):
            a = rng.uniform(t0, t1 - 0.2)
            out.append({"vehicle": rng.choice(names), "sensor": rng.choice(SENSORS),
                        "from": round(a, 3), "to": round(a + rng.uniform(0.2, 3.0), 3)})
        return out

    f = {}
    if kind in ("kill_controller", "motors_off"):
        f[kind] = {"vehicle": rng.choice(names), "time": round(rng.uniform(t0, t1), 3)}
    elif kind == "sensor_dropouts":
        f["sensor_dropouts"] = dropouts(rng.randint(1, 3))
    elif kind == "outliers":
        f["outliers"] = {"rate": round(rng.uniform(0.001, 0.05), 4),
                         "size": round(rng.uniform(0.05, 1.0), 3)}
    elif kind == "solver_failures":
        f["solver_failures"] = {"rate": round(rng.uniform(0.05, 0.5), 3)}
    else:  # mixed: dropouts, outliers and solver failures together
        f["sensor_dropouts"] = dropouts(rng.randint(1, 2))
        f["outliers"] = {"rate": round(rng.uniform(0.001, 0.02), 4),
                         "size": round(rng.uniform(0.05, 0.5), 3)}
        f["solver_failures"] = {"rate": round(rng.uniform(0.05, 0.3), 3)}
    return f


def csv_stats(run_dir):
    """NaN commands, max height and distance, and per vehicle its first ground strike in the
    NMPC phase as (time, true v_z of the row before) or None."""
    out = {"nan_commands": 0, "zmax": 0.0, "dmax": 0.0, "strikes": {}}
    for path in sorted(glob.glob(os.path.join(run_dir, "*.csv"))):
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
        if not rows:
            continue
        name = os.path.splitext(os.path.basename(path))[0]
        x0, y0 = float(rows[0]["x"]), float(rows[0]["y"])
        prev = None
        for r in rows:
            if (r["phase"] == "nmpc" and name not in out["strikes"] and
                    float(r["z"]) < REST_HEIGHT + CONTACT_MARGIN):
                out["strikes"][name] = (float(r["t"]), float((prev or r)["vz"]))
            prev = r
            out["zmax"] = max(out["zmax"], float(r["z"]))
            out["dmax"] = max(out["dmax"], math.hypot(float(r["x"]) - x0, float(r["y"]) - y0))
            if r["phase"] != "killed" and not all(math.isfinite(float(r[c]))
                                                  for c in COMMAND_COLUMNS):
                out["nan_commands"] += 1
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fnmpc", default=os.path.join(ROOT, "build/apps/fnmpc/fnmpc"))
    ap.add_argument("--scenario", default=os.path.join(ROOT, "config/scenarios/triangle.yaml"))
    ap.add_argument("--runs", type=int, default=210)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=30.0, help="fnmpc run --duration [s]")
    ap.add_argument("--out", default="", help="run folders (default: a temporary folder)")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder")
    ap.add_argument("--reality", choices=("on", "off"),
                    help="fnmpc run --reality (default: the scenario's; the triangle's is on)")
    ap.add_argument("--only", type=int, nargs="+", metavar="RUN",
                    help="fly only these run numbers (0-based) of the campaign")
    a = ap.parse_args()
    if a.runs < 1:
        ap.error("--runs must be >= 1")
    if a.only and not all(0 <= r < a.runs for r in a.only):
        ap.error(f"--only: run numbers must be in 0..{a.runs - 1}")
    with open(a.scenario) as f:
        base = yaml.safe_load(f)
    sdir = os.path.dirname(os.path.abspath(a.scenario))
    for key in ("vehicle_file", "sensors_file"):
        if key in base:
            base[key] = os.path.normpath(os.path.join(sdir, base[key]))
    for v in base["vehicles"]:
        for key in ("vehicle_file", "sensors_file"):
            if key in v:
                v[key] = os.path.normpath(os.path.join(sdir, v[key]))
    names = [v["name"] for v in base["vehicles"]]
    t0, t1 = flight_window(base, a.duration)
    rng = random.Random(a.seed)
    work = a.out or tempfile.mkdtemp(prefix="fnmpc-fault-campaign-")
    os.makedirs(work, exist_ok=True)
    stats = {k: {"runs": 0, "crashes": 0, "nan": 0, "safe": 0, "others": 0, "downed": 0,
                 "downed_safe": 0, "fell": 0, "fallbacks": 0, "injected": 0, "reinits": 0,
                 "failsafes": 0, "dropped": 0, "outliers": 0, "zmax": 0.0, "dmax": 0.0,
                 "minsep": math.inf, "bad": 0, "impact": [], "touchdown": [], "strikes": [],
                 "shifts": 0, "leaderless": 0, "departures": 0} for k in KINDS}
    failures = []
    started = time.time()
    for r in range(a.runs):
        kind = KINDS[r % len(KINDS)]
        faults = draw_faults(rng, kind, names, t0, t1)
        seed = rng.randint(1, 10**6)
        if a.only and r not in a.only:
            continue
        sc = dict(base, name=f"fault-{r:03d}-{kind}", faults=faults)
        path = os.path.join(work, f"fault-{r:03d}.yaml")
        with open(path, "w") as f:
            yaml.safe_dump(sc, f, sort_keys=False)
        out = os.path.join(work, f"run-{r:03d}")
        cmd = [a.fnmpc, "run", path, "-q", "--seed", str(seed), "--duration", str(a.duration),
               "-o", out] + (["--reality", a.reality] if a.reality else [])
        p = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        st = stats[kind]
        st["runs"] += 1
        if p.returncode not in (0, 3):
            st["crashes"] += 1
            st["bad"] += 1
            failures.append(f"run {r} ({kind}, seed {seed}): exit {p.returncode}: "
                            f"{p.stderr.strip()[-300:]}")
            continue
        with open(os.path.join(out, "run-01", "summary.json")) as f:
            s = json.load(f)
        c = csv_stats(os.path.join(out, "run-01"))
        fj = s.get("faults", {})
        downed = set(fj.get("downed_vehicles", []))
        ok = c["nan_commands"] == 0
        for name, v in s["vehicles"].items():
            if name in downed:
                st["downed"] += 1
                k = fj.get("kill_controller", {})
                if k.get("vehicle") == name:
                    st["downed_safe"] += bool(k.get("autopilot_landed"))
                    if k.get("touchdown_vertical_speed_mps") is not None:
                        st["touchdown"].append(k["touchdown_vertical_speed_mps"])
                continue
            st["others"] += 1
            st["safe"] += bool(v.get("landed_safely"))
            ok = ok and bool(v.get("landed_safely"))
            st["shifts"] += int(v.get("landing_site_shifts") or 0)
            st["departures"] += int(v.get("neighbour_departures") or 0)
            if name in c["strikes"]:
                st["strikes"].append(c["strikes"][name][1])
                ok = False
        # A collision (fnmpc run's verdict: true CoMs closer than metrics.collision_distance)
        # fails the run whoever was involved, a downed vehicle too.
        collisions = [f["reason"] for f in s.get("failures", []) if f.get("kind") == "collision"]
        ok = ok and not collisions
        if "motors_off" in fj:
            st["fell"] += 1
            if fj["motors_off"].get("impact_vertical_speed_mps") is not None:
                st["impact"].append(fj["motors_off"]["impact_vertical_speed_mps"])
        st["nan"] += c["nan_commands"]
        st["fallbacks"] += int(s.get("fallbacks") or 0)
        st["reinits"] += int(s.get("recoveries") or 0)
        st["failsafes"] += int(s.get("failsafes") or 0)
        st["leaderless"] += int(s.get("leaderless_landings") or 0)
        st["injected"] += int(fj.get("solver_failures", {}).get("injected", 0))
        st["dropped"] += sum(int(w["dropped"]) for w in fj.get("sensor_dropouts", []))
        st["outliers"] += int(fj.get("outliers", {}).get("corrupted", 0))
        st["zmax"] = max(st["zmax"], c["zmax"])
        st["dmax"] = max(st["dmax"], c["dmax"])
        if s.get("min_separation_m") is not None:
            st["minsep"] = min(st["minsep"], s["min_separation_m"])
        if not ok:
            st["bad"] += 1
            failures.append(f"run {r} ({kind}, seed {seed}): faults {json.dumps(faults)}; "
                            f"non-finite commands {c['nan_commands']}; landed safely: " +
                            ", ".join(f"{n} {v.get('landed_safely')}"
                                      for n, v in s["vehicles"].items()) +
                            "".join(f"; {n} struck the ground in flight at t = {ts:.2f} s, "
                                    f"v_z {vz:.2f} m/s" for n, (ts, vz) in c["strikes"].items()
                                    if n not in downed) +
                            "".join(f"; {reason}" for reason in collisions))
        print(f"fault-campaign: run {r} ({r + 1}/{a.runs}) {kind} {'ok' if ok else 'FAILED'} "
              f"({time.time() - started:.0f} s)", file=sys.stderr, flush=True)
    print("| fault kind | runs | crashes | non-finite commands | other vehicles landed safely | "
          "downed vehicle | injected solver "
          "failures | fallbacks | re-inits | failsafes | neighbours departed | "
          "leaderless landings | landing sites moved | "
          "ground strikes in flight | dropped / outlier measurements | "
          "max z [m] | max distance from start [m] | min separation [m] | runs failing a check |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    tot = {"runs": 0, "bad": 0}
    for k in KINDS:
        st = stats[k]
        if st["runs"] == 0:
            continue
        tot["runs"] += st["runs"]
        tot["bad"] += st["bad"]
        downed = "–"
        if st["touchdown"]:
            downed = (f"{st['downed_safe']}/{st['downed']} landed by the autopilot (touchdown v_z "
                      f"{min(st['touchdown']):.2f} to {max(st['touchdown']):.2f} m/s)")
        elif st["downed"]:
            imp = (f" (impact v_z {min(st['impact']):.1f} to {max(st['impact']):.1f} m/s)"
                   if st["impact"] else "")
            downed = f"{st['fell']}/{st['downed']} fell{imp}"
        strikes = (f"{len(st['strikes'])} (v_z {min(st['strikes']):.2f} to "
                   f"{max(st['strikes']):.2f} m/s)" if st["strikes"] else "0")
        print(f"| {k} | {st['runs']} | {st['crashes']} | {st['nan']} | "
              f"{st['safe']}/{st['others']} | {downed} | {st['injected']} | {st['fallbacks']} | "
              f"{st['reinits']} | {st['failsafes']} | {st['departures']} | {st['leaderless']} | "
              f"{st['shifts']} | {strikes} | "
              f"{st['dropped']} / {st['outliers']} | "
              f"{st['zmax']:.2f} | {st['dmax']:.2f} | "
              f"{st['minsep'] if math.isinf(st['minsep']) else round(st['minsep'], 2)} | "
              f"{st['bad']} |")
    print(f"\n{tot['runs']} runs, {tot['bad']} failing a check, wall time "
          f"{time.time() - started:.0f} s", file=sys.stderr)
    for line in failures:
        print("fault-campaign: " + line, file=sys.stderr)
    if not a.out and not a.keep:
        shutil.rmtree(work, ignore_errors=True)
    elif not a.out:
        print(f"fault-campaign: runs kept in {work}", file=sys.stderr)
    return 1 if tot["bad"] else 0


if __name__ == "__main__":
    sys.exit(main())
