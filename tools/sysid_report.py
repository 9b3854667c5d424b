#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Plots and summary of `fnmpc sysid` / `fnmpc calibrate` from the CSV dumps they write.

Usage: MPLBACKEND=Agg /usr/bin/python3 tools/sysid_report.py REPORT_DIR
REPORT_DIR holds summary.json and the CSVs; this writes one PNG per fit and summary.md.
"""
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]} if rows else {}


def save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def fmt_num(x):
    return "-" if x is None else ("%.6g" % x if isinstance(x, (int, float)) else str(x))


def pct(x):
    return "-" if x is None else f"{x:.1f} %"


def stage_lines(stages):
    """summary.md section per stage: parameters with standard errors, residuals, checks."""
    lines = []
    for st in stages:
        status = ("sanity " + st["sanity"]) if st["ok"] else "FAILED"
        lines += ["", f"## Stage: {st['name']} ({status})", ""]
        if not st["ok"]:
            lines += [f"Reason: `{st['reason']}`", ""]
            continue
        lines += ["| parameter | value | std. error | unit |", "|---|---|---|---|"]
        for p in st["params"]:
            if p["value"] is None:
                continue
            lines.append(f"| {p['name']} | {fmt_num(p['value'])} | {fmt_num(p['std_error'])} | "
                         f"{p['unit']} |")
        if st["residuals"]:
            lines += ["", "Residuals and fit statistics: " + ", ".join(
                f"{k} {fmt_num(v)}" for k, v in sorted(st["residuals"].items())), ""]
        lines += ["| sanity check | value | limit | result |", "|---|---|---|---|"]
        for c in st["checks"]:
            lines.append(f"| {c['name']} | {fmt_num(c['value'])} | {c['limit']} | "
                         f"{'PASS' if c['pass'] else 'FAIL'} |")
    return lines


def sysid_report(d, s):
    stages = {st["name"]: st for st in s.get("stages", [])}
    ok = {name: st["ok"] for name, st in stages.items()}
    if ok.get("propulsion", False):
        bench_plot(d)
    if ok.get("inertia", False):
        pendulum_plots(d, s)
    if ok.get("attitude model", False):
        attitude_plots(d, s)
    lines = [f"# System identification: {s.get('name', '')}", "",
             f"Campaign: `{s['campaign']}`", "",
             "Vehicle file: " + ("complete" if s.get("complete") else
                                 "**INCOMPLETE** (failed stages below)"), ""]
    lines += stage_lines(s.get("stages", []))
    lines += validation_lines(s)
    lines += ["", "Plots: bench.png, pendulum_{x,y,z}.png, attitude_{roll,pitch,yaw}.png "
              "(of the stages that ran)", ""]
    with open(os.path.join(d, "summary.md"), "w") as f:
        f.write("\n".join(lines))


def validation_lines(s):
    """Gaps, model selection and held-out fit per axis (docs/sysid.md)."""
    lines = []
    g = s.get("gaps")
    if g is not None:
        lines += ["", "## Gaps in the attitude log", "",
                  f"{g['count']} gap(s) (time step > {g['factor']} x the median); "
                  f"{g['excluded_samples']} of {g['samples']} samples left out of the fits "
                  f"(up to {g['settle']} s after each gap)."]
        if g["intervals"]:
            lines += [""] + [f"- {a:.3f} - {b:.3f} s" for a, b in g["intervals"][:50]]
            if len(g["intervals"]) > 50:
                lines.append(f"- ... {len(g['intervals']) - 50} more (summary.json)")
    att = s.get("attitude", {})
    if any("validation" in att.get(a, {}) for a in ("roll", "pitch", "yaw")):
        lines += ["", "## Model selection and held-out validation", "",
                  "| axis | held-out fit, first order | held-out fit, PD loop | RMS first order "
                  "[rad] | RMS PD loop [rad] | margin (folds) | written | transport delay |",
                  "|---|---|---|---|---|---|---|---|"]
        for a in ("roll", "pitch", "yaw"):
            at = att.get(a, {})
            v = at.get("validation")
            if v is None:
                continue
            fm = v.get("fold_margins") or [None, None]
            folds = ", ".join("-" if x is None else f"{100 * x:+.1f} %" for x in fm)
            m = v.get("margin")
            lines.append(
                f"| {a} | {pct(v.get('first_order_fit_percent'))} | "
                f"{pct(v.get('pd_loop_fit_percent'))} | {fmt_num(v.get('first_order_rms'))} | "
                f"{fmt_num(v.get('pd_loop_rms'))} | "
                f"{'-' if m is None else f'{100 * m:+.1f} %'} ({folds}) | {at['delay_model']} | "
                f"{1000 * at['transport_delay']:.1f} ms"
                f"{'' if at.get('transport_delay_identifiable') else ' (not identifiable)'} |")
        for w in s.get("warnings", []):
            lines += ["", f"Warning: {w}"]
    return lines


def bench_plot(d):
    b = read_csv(os.path.join(d, "bench.csv"))
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    rpm2 = [r * r for r in b["rpm"]]
    ax[0].plot(rpm2, b["thrust"], ".", label="bench")
    ax[0].plot(rpm2, b["thrust_fit"], "-", label="T_k rpm^2")
    ax[0].set_xlabel("rpm^2")
    ax[0].set_ylabel("thrust [N]")
    ax[0].legend()
    ax[1].plot(rpm2, b["torque"], ".", label="bench")
    ax[1].plot(rpm2, b["torque_fit"], "-", label="T_q rpm^2")
    ax[1].set_xlabel("rpm^2")
    ax[1].set_ylabel("torque [N m]")
    ax[1].legend()
    sc = ax[2].scatter(b["thrust"], [t - f for t, f in zip(b["throttle"], b["throttle_fit"])],
                       c=b["voltage"], s=8)
    fig.colorbar(sc, ax=ax[2], label="voltage [V]")
    ax[2].set_xlabel("thrust [N]")
    ax[2].set_ylabel("throttle residual [-]")
    ax[2].set_title("cubic thrust-throttle-voltage fit")
    save(fig, os.path.join(d, "bench.png"))


def pendulum_plots(d, s):
    for axis in "xyz":
        p = read_csv(os.path.join(d, f"pendulum_{axis}.csv"))
        fig, ax = plt.subplots(figsize=(10, 3.5))
        ax.plot(p["t"], p["angle"], ".", ms=2, label="measured")
        ax.plot(p["t"], p["fit"], "-", lw=1, label="damped sinusoid fit")
        pe = s["pendulum"][axis]
        ax.set_title(f"pendulum {axis}: T = {pe['natural_period']:.4f} s, "
                     f"I = {pe['inertia']:.5f} kg m^2")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("angle [rad]")
        ax.legend()
        save(fig, os.path.join(d, f"pendulum_{axis}.png"))


def attitude_plots(d, s):
    for axis in ("roll", "pitch", "yaw"):
        a = read_csv(os.path.join(d, f"attitude_{axis}.csv"))
        at = s["attitude"][axis]
        fig, (ax, hx) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
        ax.plot(a["t"], a["ref"], "k--", lw=1, label="reference")
        ax.plot(a["t"], a["angle"], ".", ms=2, label="feedback (measured)")
        ax.plot(a["t"], a["first_order"], "-", lw=1.2,
                label=f"first order: tau {at['time_constant']:.4f} + delay {at['delay']:.4f} s, "
                      f"k {at['gain']:.3f}")
        if "kp" in at:
            ax.plot(a["t"], a["pd_loop"], ":", lw=1.2,
                    label=f"sim PD loop: K_p {at['kp']:.1f}, K_d {at['kd']:.2f}, "
                          f"delay {at['pd_delay']:.3f} s")
        ax.set_ylabel(f"{axis} [rad]")
        ax.set_title(f"{axis}: fits on all samples; written: {at.get('delay_model', '')}",
                     fontsize=9)
        ax.legend(fontsize=8)
        # Held-out segments: each sample predicted by the model fitted on the other fold.
        val = at.get("validation", {})
        hx.plot(a["t"], a["angle"], ".", ms=2, color="0.5", label="measured")
        hx.plot(a["t"], a["heldout_first_order"], "-", lw=1.2,
                label=f"first order, held out: fit {pct(val.get('first_order_fit_percent'))}")
        hx.plot(a["t"], a["heldout_pd_loop"], ":", lw=1.2,
                label=f"PD loop, held out: fit {pct(val.get('pd_loop_fit_percent'))}")
        # Samples left out after gaps in the log.
        t, used = a["t"], a["used"]
        start = None
        for i, u in enumerate(used + [1.0]):
            if u == 0.0 and start is None:
                start = t[i]
            elif u != 0.0 and start is not None:
                hx.axvspan(start, t[i - 1], color="red", alpha=0.15, lw=0)
                start = None
        margin = val.get("margin")
        hx.set_title("held-out segments (NRMSE fit); margin "
                     + ("-" if margin is None else f"{100 * margin:+.1f} %")
                     + (" (decisive)" if val.get("decisive") else " (undecided)")
                     + "; red: left out after a gap", fontsize=9)
        hx.set_xlabel("t [s]")
        hx.set_ylabel(f"{axis} [rad]")
        hx.legend(fontsize=8)
        save(fig, os.path.join(d, f"attitude_{axis}.png"))


def calibrate_report(d, s):
    w = read_csv(os.path.join(d, "windows.csv"))
    fig, ax = plt.subplots(3, 1, figsize=(11, 8), sharex=True)
    windows = sorted(set(int(k) for k in w["window"]))
    for i, name in enumerate("xyz"):
        ax[i].plot(w["t"], w[name], "k.", ms=2, label="logged")
        for k in windows:
            idx = [j for j, v in enumerate(w["window"]) if int(v) == k]
            t = [w["t"][j] for j in idx]
            ax[i].plot(t, [w[name + "_before"][j] for j in idx], "r-", lw=0.8,
                       label="predicted, before" if k == windows[0] else None)
            ax[i].plot(t, [w[name + "_after"][j] for j in idx], "b-", lw=0.8,
                       label="predicted, calibrated" if k == windows[0] else None)
        ax[i].set_ylabel(f"{name} [m]")
    ax[0].legend(fontsize=8)
    ax[0].set_title(f"{s['window']} s open-loop windows: mean position error "
                    f"{s['position_error_before']:.4f} m before, {s['position_error_after']:.4f} m after")
    ax[2].set_xlabel("t [s]")
    save(fig, os.path.join(d, "trajectories.png"))

    c = read_csv(os.path.join(d, "commands.csv"))
    fig, ax = plt.subplots(3, 1, figsize=(11, 8), sharex=True)
    ax[0].plot(c["t"], c["thrust_cmd"], "b-", lw=1, label="commanded")
    ax[0].plot(c["t"], c["thrust_after"], "r--", lw=1, label="produced (calibrated scale)")
    ax[0].set_ylabel("thrust [N]")
    for i, name in ((1, "roll"), (2, "pitch")):
        ax[i].plot(c["t"], c[name + "_cmd"], "b-", lw=1, label="commanded")
        ax[i].plot(c["t"], c[name + "_after"], "r--", lw=1, label="commanded + bias")
        ax[i].plot(c["t"], c[name], "k.", ms=1.5, label="measured")
        ax[i].set_ylabel(f"{name} [rad]")
    for a in ax:
        a.legend(fontsize=8)
    ax[2].set_xlabel("t [s]")
    save(fig, os.path.join(d, "commands.png"))

    deg = 180.0 / 3.141592653589793
    lines = ["# Simulator calibration", "", f"Vehicle `{s['vehicle']}`, flight `{s['flight']}`", "",
             "| quantity | value |", "|---|---|",
             f"| roll bias | {s['bias_roll']:.5f} rad ({s['bias_roll'] * deg:.3f} deg) |",
             f"| pitch bias | {s['bias_pitch']:.5f} rad ({s['bias_pitch'] * deg:.3f} deg) |",
             f"| thrust scale | {s['thrust_scale']:.4f} |",
             f"| mean position error, before | {s['position_error_before']:.4f} m |",
             f"| mean position error, after | {s['position_error_after']:.4f} m |",
             f"| windows | {s['windows']} x {s['window']} s, every {s['window_stride']} s |",
             ""] + stage_lines(s.get("stages", [])) + ["", "Plots: trajectories.png, commands.png", ""]
    with open(os.path.join(d, "summary.md"), "w") as f:
        f.write("\n".join(lines))


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    d = sys.argv[1]
    with open(os.path.join(d, "summary.json")) as f:
        s = json.load(f)
    if s["kind"] == "sysid":
        sysid_report(d, s)
    else:
        calibrate_report(d, s)


if __name__ == "__main__":
    main()
