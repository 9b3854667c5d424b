#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Validation plots of the simulator's reality models (docs/simulator.md, "Validation against
published measurements"): runs the model side (the C++ tool reality_validation, built with the
project) and draws it beside the published numbers.

    cmake --build build -j1 --target reality_validation
    /usr/bin/python3 tools/reality_validation.py --exe build/tools/reality_validation

writes docs/validation-propeller.png, docs/validation-wake.png, docs/validation-force.png,
docs/validation-wake-quadrotor.png and docs/validation-force-crazyflie.png and prints the tables
of docs/simulator.md."""
import argparse
import csv
import io
import math
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
UIUC = os.path.join(ROOT, "tests", "sim", "data", "uiuc_apc10x7_4011rpm.csv")
CRAZYFLIE = os.path.join(ROOT, "tests", "sim", "data", "neural_swarm_fig3_crazyflie.csv")
# Round turbulent jet, laser-Doppler measurements of Hussein, Capp and George (1994, J. Fluid
# Mech. 258), as tabulated in Pope (2000, Turbulent Flows, Table 5.1): U_c = B d U_J / (x - x0)
# with d U_J = sqrt(4 M / (pi rho)) for momentum flux M, half width r_1/2 = S (x - x0).
JET_B = 5.8
JET_S = 0.094
RHO = 1.225
# Far-field fit below hovering quadrotors of Bauersfeld et al. (IEEE RA-L 2024, arXiv
# 2403.13321), as transcribed with the paper's equation numbers in github.com/learnsyslab/
# crazyflow examples/plugins/downwash.py (commit 4b32a459608c2de120dcb86fea941ee572dbf129):
# Eq. (9) B_d, S, s_0; U_c / U_H = B_d / (s/l - s_0); r_1/2 / l = S (s/l - s_0);
# U = U_c / (1 + (sqrt2 - 1) (r / r_1/2)^2)^2; l the distance between opposite motors.
FIT_BD = 10.11
FIT_S = 0.07668
FIT_S0 = -5.817


def fit_centre(s_l):
    return FIT_BD / (s_l - FIT_S0)


def fit_half_width(s_l):
    return FIT_S * (s_l - FIT_S0)


def fit_velocity(s_l, r_l):
    xi = r_l / fit_half_width(s_l)
    return fit_centre(s_l) / (1 + (math.sqrt(2) - 1) * xi * xi) ** 2


def blocks(text):
    """CSV blocks of the tool's output, keyed by their [name] line."""
    out, name, lines = {}, None, []
    for line in text.splitlines():
        if line.startswith("["):
            if name:
                out[name] = lines
            name, lines = line.strip("[]"), []
        elif line.strip():
            lines.append(line)
    if name:
        out[name] = lines
    return out


def rows(lines):
    """Rows of one block as dicts of floats; a block may hold a one-row preamble table."""
    return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(io.StringIO("\n".join(lines)))]


def table(path):
    with open(path) as f:
        data = [line for line in f if not line.startswith("#")]
    return rows(data)


def uiuc():
    return table(UIUC)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--exe", default=os.path.join(ROOT, "build", "tools", "reality_validation"))
    ap.add_argument("--out", default=os.path.join(ROOT, "docs"))
    a = ap.parse_args()
    text = subprocess.run([a.exe, UIUC, CRAZYFLIE], check=True, capture_output=True, text=True).stdout
    b = blocks(text)

    # --- Propeller in axial inflow.
    model = rows(b["propeller"])
    data = uiuc()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot([r["J"] for r in model], [r["ct_model"] for r in model], "-", label="simulator (BEMT, default blade; pitch from the first point)")
    ax.plot([r["J"] for r in data], [r["CT"] for r in data], "o", label="UIUC, APC 10x7 at 4011 RPM (measured)")
    ax.axvline(0.40, color="0.6", ls=":", lw=1)
    ax.text(0.405, 0.02, "J = 0.40: 10 m/s inflow\nat our hover rotor speed", fontsize=8, color="0.4")
    ax.set_xlabel("advance ratio J = V / (n D)")
    ax.set_ylabel("C_T = T / (rho n^2 D^4)")
    ax.set_xlim(0, 0.8)
    ax.set_ylim(0, 0.17)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Propeller thrust in axial inflow")
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "validation-propeller.png"), dpi=110)
    print("| J | C_T measured (UIUC) | C_T simulator | error [% of C_T(0.144)] |")
    print("|---|---|---|---|")
    by_j = {round(r["J"], 2): r["ct_model"] for r in model}
    for r in data:
        # the model on the data's J (the tool's grid is 0.01; interpolate linearly)
        j = r["J"]
        j0 = math.floor(j * 100) / 100
        j1 = j0 + 0.01
        m = by_j[round(j0, 2)] + (by_j[round(j1, 2)] - by_j[round(j0, 2)]) * (j - j0) / 0.01
        print(f"| {j:.3f} | {r['CT']:.4f} | {m:.4f} | {100 * (m - r['CT']) / data[0]['CT']:+.1f} |")

    # --- Wake: centreline decay against the round-jet measurements, radial profiles.
    head = rows(b["wake"][:2])[0]
    thrust, v_h, diam = head["thrust"], head["v_h"], head["rotor_diameter"]
    prof = rows(b["wake"][2:])
    cl = rows(b["centreline"])
    r0, s_model = 0.3, 0.094  # DownwashSettings defaults: wake_radius, spreading_rate
    d_uj = math.sqrt(4 * thrust / (math.pi * RHO))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4.2))
    s_d = [r["s_over_D"] for r in cl]
    a1.plot(s_d, [r["uc_over_vh"] for r in cl], "-", label="simulator U_c")
    x0 = -r0 / s_model  # the simulator's virtual origin, used for the measured decay too
    a1.plot(s_d, [JET_B * d_uj / (s * diam - x0) / v_h for s in s_d], "--",
            label="round jet, B = 5.8 (Hussein et al. 1994)")
    a1.set_xlabel("distance below the rotor plane s / D (D = rotor diameter)")
    a1.set_ylabel("centreline velocity U_c / v_h")
    a1.grid(alpha=0.3)
    a1.legend(fontsize=8)
    a1.set_title(f"Centreline velocity, shipped vehicle hovering ({thrust:.1f} N)")
    for s in sorted({r["s_over_D"] for r in prof}):
        pts = [r for r in prof if r["s_over_D"] == s]
        a2.plot([r["r_over_D"] for r in pts], [r["u_over_vh"] for r in pts], label=f"s = {s:g} D")
    a2.set_xlabel("distance from the axis r / D")
    a2.set_ylabel("downward velocity U / v_h")
    a2.grid(alpha=0.3)
    a2.legend(fontsize=8)
    a2.set_title("Radial profiles (simulator only)")
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "validation-wake.png"), dpi=110)
    print()
    print("| s / D | simulator U_c [m/s] | round jet B = 5.8 [m/s] | ratio |")
    print("|---|---|---|---|")
    for r in cl:
        if r["s_over_D"] in (2.0, 4.0, 6.0, 10.0, 20.0):
            jet = JET_B * d_uj / (r["s_over_D"] * diam - x0)
            print(f"| {r['s_over_D']:g} | {r['uc_over_vh'] * v_h:.2f} | {jet:.2f} | {r['uc_over_vh'] * v_h / jet:.3f} |")

    # --- Force on a vehicle hovering below another.
    f = rows(b["force"])
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    sep = [r["separation_D"] for r in f]
    ax.errorbar(sep, [-r["fz_on_mean"] for r in f], yerr=[r["fz_on_sd"] for r in f], fmt="o-",
                capsize=3, label="reality on: mean ± sd (rotor inflow + advected turbulent wake)")
    ax.plot(sep, [-r["fz_off"] for r in f], "s--", label="reality off: steady jet as body drag")
    ax.set_xlabel("vertical separation / rotor diameter")
    ax.set_ylabel("downward aerodynamic force on the lower vehicle [N]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Vehicle hovering below another (simulator)")
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "validation-force.png"), dpi=110)
    print()
    print("| separation [D] | [m] | reality on: -aero_fz mean ± sd [N] | lateral sd [N] | share of weight | reality off [N] |")
    print("|---|---|---|---|---|---|")
    for r in f:
        print(f"| {r['separation_D']:g} | {r['separation_D'] * diam:.2f} | {-r['fz_on_mean']:.2f} ± {r['fz_on_sd']:.2f} | "
              f"{r['fxy_on_sd']:.2f} | {-r['fz_on_mean'] / r['weight'] * 100:.0f} % | {-r['fz_off']:.2f} |")

    # --- Wake below a hovering quadrotor against the quadrotor far-field fit (U/U_H vs s/l).
    head = rows(b["quadrotor_wake"][:2])[0]
    l = head["motor_distance"]
    qw = rows(b["quadrotor_wake"][2:])
    qp = rows(b["quadrotor_profiles"])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4.2))
    s_l = [r["s_over_l"] for r in qw]
    a1.plot(s_l, [r["uc_over_uh"] for r in qw], "-", label="simulator")
    fit_s = [x for x in s_l if x >= 2.5]
    a1.plot(fit_s, [fit_centre(x) for x in fit_s], "--", label="fit of Bauersfeld et al. (third-party transcription)")
    a1.axvspan(0, 2.5, color="0.9")
    a1.text(0.15, 0.2, "near field:\nfit not valid", fontsize=8, color="0.4")
    a1.set_xlabel("distance below the vehicle s / l (l = distance between opposite motors)")
    a1.set_ylabel("centreline velocity U_c / U_H")
    a1.set_xlim(0, 20)
    a1.set_ylim(0, 2.1)
    a1.grid(alpha=0.3)
    a1.legend(fontsize=8)
    a1.set_title(f"Centreline, shipped vehicle hovering (l = {l:.2f} m)")
    for i, sv in enumerate((3.0, 5.0, 8.0)):
        pts = [r for r in qp if r["s_over_l"] == sv]
        a2.plot([r["r_over_l"] for r in pts], [r["u_over_uh"] for r in pts], "-", color=f"C{i}", label=f"simulator s = {sv:g} l")
        a2.plot([r["r_over_l"] for r in pts], [fit_velocity(sv, r["r_over_l"]) for r in pts], "--", color=f"C{i}", label=f"fit s = {sv:g} l")
    a2.axvline(0.5, color="0.6", ls=":", lw=1)
    a2.text(0.52, 0.02, "rotors of a vehicle\ndirectly below (r = l/2)", fontsize=8, color="0.4")
    a2.set_xlabel("distance from the axis r / l")
    a2.set_ylabel("downward velocity U / U_H")
    a2.grid(alpha=0.3)
    a2.legend(fontsize=7)
    a2.set_title("Radial profiles")
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "validation-wake-quadrotor.png"), dpi=110)
    print()
    print("| s / l | U_c/U_H simulator | U_c/U_H fit | ratio | U(r=l/2)/U_H simulator | fit | ratio | r_1/2 / l simulator | fit | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    by_s = {round(r["s_over_l"], 1): r for r in qw}
    prof = {(round(r["s_over_l"], 1), round(r["r_over_l"], 2)): r["u_over_uh"] for r in qp}
    for sv in (2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 20.0):
        r = by_s[sv]
        line = f"| {sv:g} | {r['uc_over_uh']:.3f} | {fit_centre(sv):.3f} | {r['uc_over_uh'] / fit_centre(sv):.3f} | "
        u = prof[(sv, 0.5)]
        line += f"{u:.3f} | {fit_velocity(sv, 0.5):.3f} | {u / fit_velocity(sv, 0.5):.3f} | "
        line += f"{r['half_width_over_l']:.3f} | {fit_half_width(sv):.3f} | {r['half_width_over_l'] / fit_half_width(sv):.3f} |"
        print(line)

    # --- Force on the lower vehicle per weight against the Crazyflie measurement (s/l).
    cf = table(CRAZYFLIE)
    fw = rows(b["force_per_weight"])
    data_s = [r["separation_m"] / r["motor_distance_m"] for r in cf]
    grid = sorted((r for r in fw if all(abs(r["s_over_l"] - x) > 1e-3 for x in data_s)), key=lambda r: r["s_over_l"])
    at_data = {round(r["s_over_l"], 3): r for r in fw}
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.fill_between([r["s_over_l"] for r in grid], [r["fz_over_weight"] - r["fz_sd_over_weight"] for r in grid],
                    [r["fz_over_weight"] + r["fz_sd_over_weight"] for r in grid], color="C0", alpha=0.15)
    ax.plot([r["s_over_l"] for r in grid], [r["fz_over_weight"] for r in grid], "-", color="C0",
            label="simulator, shipped vehicle: mean (band: ± sd)")
    ax.plot(data_s, [r["force_g"] / r["weight_g"] for r in cf], "o", color="C3",
            label="Crazyflies, Neural-Swarm Fig. 3 (third-party reading)")
    ax.set_xlabel("vertical distance / distance between opposite motors (s / l)")
    ax.set_ylabel("downward force on the lower vehicle / its weight")
    ax.set_ylim(0, 0.8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Vehicle hovering directly below another, normalised")
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "validation-force-crazyflie.png"), dpi=110)
    print()
    print("| s / l | Crazyflie s [m] | measured F / W | shipped vehicle s [m] | simulated F / W (± sd) | ratio |")
    print("|---|---|---|---|---|---|")
    for r, x in zip(cf, data_s):
        m = at_data[round(x, 3)]
        meas = r["force_g"] / r["weight_g"]
        print(f"| {x:.2f} | {r['separation_m']:.1f} | {meas:.3f} | {x * l:.2f} | "
              f"{m['fz_over_weight']:.3f} ± {m['fz_sd_over_weight']:.3f} | {m['fz_over_weight'] / meas:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
