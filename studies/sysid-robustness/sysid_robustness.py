#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Robustness study of `fnmpc sysid` + `fnmpc calibrate` (docs/sysid.md "Robustness study").

    PATH=/usr/bin:$PATH /usr/bin/python3 studies/sysid-robustness/sysid_robustness.py FNMPC [OUTDIR]

For each variation of the synthetic campaign (`fnmpc sysid synth` from the project's
simulator: transport delay, logging rate, noise, half the data, a DC-motor throttle map,
attitude biases in the step log) it runs sysid and calibrate and compares every parameter
with the synthesiser's truth under the tolerances of ../shared/sysid-dev/check_sysid.py
(mass 1 %, inertia 5 %, T_k/T_q 3 %, tau 8 %, gain 3 %, throttle 0.02 on 2-8 N x
15-16.8 V, biases 0.3 deg, thrust scale 0.01). Prints a Markdown table of the errors (a
failed parameter is marked **bold**) and exits 1 when any parameter fails.
"""
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
import yaml

VARIATIONS = [
    ("nominal", []),
    ("delay 10 ms", ["--delay", "0.010"]),
    ("delay 20 ms", ["--delay", "0.020"]),
    ("delay 30 ms", ["--delay", "0.030"]),
    ("log 50 Hz", ["--log-rate", "50"]),
    ("log 100 Hz", ["--log-rate", "100"]),
    ("log 200 Hz", ["--log-rate", "200"]),
    ("noise x0.5", ["--noise-scale", "0.5"]),
    ("noise x3", ["--noise-scale", "3"]),
    ("half data", ["--data-fraction", "0.5"]),
    ("DC motor map", ["--motor-map", "dc"]),
    ("attitude bias in steps", ["--attitude-bias"]),
    ("delay 20 ms + 100 Hz + noise x2", ["--delay", "0.020", "--log-rate", "100",
                                        "--noise-scale", "2"]),
]
GRID_F = np.linspace(2.0, 8.0, 61)
GRID_V = np.linspace(15.0, 16.8, 37)


def poly(coeffs, F, V):
    out = np.zeros(np.broadcast(F, V).shape)
    for i, row in enumerate(coeffs):
        for j, c in enumerate(row):
            out = out + float(c) * F ** i * V ** j
    return out


def compare(truth, veh, motor):
    """(name, error, tolerance, unit) rows; error None when the parameter is missing."""
    rows = []

    def rel(name, t, v, tol):
        rows.append((name, None if v is None else (v - t) / t, tol, "%"))

    rel("mass", truth["mass"], veh.get("mass"), 0.01)
    for k, ax in enumerate("xyz"):
        rel("I_" + ax, truth["inertia"][k], (veh.get("inertia") or [None] * 3)[k], 0.05)
    rel("T_k", truth["thrust_constant"], veh.get("thrust_constant"), 0.03)
    rel("T_q", truth["torque_constant"], veh.get("torque_constant"), 0.03)
    att = veh.get("attitude") or {}
    for key, label, tol in (("time_constant", "tau", 0.08), ("gain", "k", 0.03)):
        for k, ax in enumerate(("roll", "pitch", "yaw")):
            rel(f"{label} {ax}", truth["attitude"][key][k], (att.get(key) or [None] * 3)[k], tol)
    FF, VV = np.meshgrid(GRID_F, GRID_V)
    if motor:
        w = np.sqrt(FF / motor["thrust_constant"])
        tt = (motor["a"] * w * w + motor["b"] * w + motor["c"]) / VV
    else:
        tt = poly(truth["throttle_polynomial"]["coefficients"], FF, VV)
    c = (veh.get("throttle_polynomial") or {}).get("coefficients")
    rows.append(("throttle", None if c is None else float(np.max(np.abs(poly(c, FF, VV) - tt))),
                 0.02, "abs"))
    b, tb = veh.get("bias") or {}, truth["bias"]
    for key in ("roll", "pitch"):
        v = b.get(key)
        rows.append((f"bias {key}", None if v is None else math.degrees(v - tb[key]), 0.3, "deg"))
    v = b.get("thrust")
    rows.append(("thrust scale", None if v is None else v - tb["thrust"], 0.01, "abs"))
    return rows


def run(cmd, cwd):
    p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return p.returncode, p.stdout


def main(argv):
    if len(argv) not in (2, 3):
        print(__doc__)
        return 2
    fnmpc = os.path.abspath(argv[1])
    base = argv[2] if len(argv) == 3 else tempfile.mkdtemp(prefix="fnmpc_robustness_")
    table, names, all_ok = [], None, True
    for label, args in VARIATIONS:
        d = os.path.join(base, label.replace(" ", "_").replace("+", "").replace(".", ""))
        os.makedirs(d, exist_ok=True)
        rc, out = run([fnmpc, "sysid", "synth", "c"] + args, d)
        if rc != 0:
            print(out)
            return 1
        rc1, out1 = run([fnmpc, "sysid", "c/campaign.yaml", "-o", "vehicle.yaml", "--no-plots"],
                        d)
        rc2, out2 = run([fnmpc, "calibrate", "vehicle.yaml", "c/flight.csv", "-o",
                         "calibrated.yaml", "--no-plots"], d)
        path = os.path.join(d, "calibrated.yaml" if rc2 in (0, 3) else "vehicle.yaml")
        with open(path) as f:
            veh = yaml.safe_load(f) or {}
        with open(os.path.join(d, "c", "truth.yaml")) as f:
            truth = yaml.safe_load(f)
        motor = None
        if os.path.exists(os.path.join(d, "c", "truth_motor.yaml")):
            with open(os.path.join(d, "c", "truth_motor.yaml")) as f:
                motor = yaml.safe_load(f)
        rows = compare(truth, veh, motor)
        names = [r[0] for r in rows]
        cells, fails = [], 0
        for name, err, tol, unit in rows:
            if err is None:
                cells.append("**missing**")
                fails += 1
                continue
            ok = abs(err) <= tol
            fails += 0 if ok else 1
            txt = "%+.1f" % (100 * err) if unit == "%" else ("%+.3f" % err if unit != "abs" else
                                                              "%.3f" % err if name == "throttle"
                                                              else "%+.4f" % err)
            cells.append(txt if ok else "**" + txt + "**")
        all_ok = all_ok and fails == 0
        table.append([label, f"{len(rows) - fails}/{len(rows)}", f"{rc1}/{rc2}"] + cells)
        print(f"{label}: {len(rows) - fails}/{len(rows)} within tolerance (exit {rc1}/{rc2})",
              file=sys.stderr, flush=True)
    head = ["variation", "pass", "exit sysid/cal"] + names
    units = ["", "", ""] + ["%" if n in ("mass", "T_k", "T_q") or n[:2] in ("I_", "ta", "k ")
                            else ("deg" if n.startswith("bias") else "abs") for n in names]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    print("| " + " | ".join(units) + " |")
    for r in table:
        print("| " + " | ".join(r) + " |")
    return 0 if all_ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
