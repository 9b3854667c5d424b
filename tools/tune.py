#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Tunes the followers' NMPC weights with Optuna (docs/tuning.md).

`fnmpc tune` runs this script. Each trial scales the scenario's own
`controller.weights.follower` by factors Optuna's TPE sampler proposes, flies every tuning
scenario for --seeds seeds through `fnmpc campaign` (the same executors: local, slurm, dask)
and scores the mean over the scenarios of the worst-follower mean formation error in the
formation window (`mean_formation_error_m`). A trial with more NMPC fallbacks than the
defaults, or with a failed vehicle, is infeasible: it scores its error times 10 and is never
chosen as best. Trial 0 is the defaults. At the end the best weights and the defaults fly
the held-out scenarios (not used in tuning) on --held-out-seeds other seeds.

  tools/tune.py --fnmpc FNMPC --trials N --held-out H.yaml... [--seeds 3]
      [--held-out-seeds 10] [--executor local|slurm|dask] [--storage URL] [--study NAME]
      [--duration T] [-o OUT] [-q] SCENARIO.yaml...

Writes OUT/tune.json (every trial, the best factors and weights, the held-out table),
OUT/tuned-weights.yaml (the `controller.weights.follower` block to use), OUT/history.png and
OUT/trials/ (each evaluation's campaign folders). Exit 0 when the tuned weights are at least as
good as the defaults on the held-out scenarios with no more fallbacks, 3 otherwise (both
reported), 1 on an error, 130/143 when stopped.
"""
import argparse
import hashlib
import json
import math
import os
import signal
import subprocess
import sys
import time

import yaml

# Factors on the scenario's own follower weights; log-uniform in [LOW, HIGH].
LOW, HIGH = 0.2, 5.0
FACTORS = ["position_xy", "position_z", "velocity", "attitude_ref", "thrust", "terminal_factor"]
TUNING_SEED, HELD_OUT_SEED = 1000, 2000  # first seeds: tuning and held-out runs never share one
INFEASIBLE = 10.0  # score factor of a trial with more fallbacks or a failed vehicle


class TuneError(Exception):
    pass


def load_scenario(path):
    try:
        with open(path, encoding="utf-8") as f:
            doc = yaml.safe_load(f)
    except OSError as e:
        raise TuneError(f"{path}: cannot read: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise TuneError(f"{path}: key '(top level)': not valid UTF-8 (byte offset {e.start})") \
            from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        raise TuneError(f"{path}:{mark.line + 1 if mark else 1}: key '(top level)': not valid "
                        f"YAML: {getattr(e, 'problem', None) or e}") from None
    if not isinstance(doc, dict):
        raise TuneError(f"{path}: not a scenario (a YAML map expected)")
    base = os.path.dirname(os.path.abspath(path))

    def absolute(node):  # file references relative to the scenario stay valid in OUT
        if isinstance(node, dict):
            for k, v in node.items():
                if k.endswith("_file") and isinstance(v, str) and not os.path.isabs(v):
                    node[k] = os.path.normpath(os.path.join(base, v))
                else:
                    absolute(v)
        elif isinstance(node, list):
            for v in node:
                absolute(v)

    absolute(doc)
    return doc


EFFECTIVE = {}  # scenario path -> the follower weights it flies with (from fnmpc tune)


def follower_weights(doc, path):
    """The scenario's follower weights: its own keys over the effective values fnmpc computed
    (the struct's defaults for keys the file leaves out)."""
    w = {k: yaml.safe_load(v) for k, v in EFFECTIVE.get(path, {}).items()}
    own = ((doc.get("controller") or {}).get("weights") or {}).get("follower") or {}
    if not isinstance(own, dict):
        raise TuneError(f"{path}: key 'controller.weights.follower': not a map")
    w.update(own)
    for key in ("position", "velocity", "thrust", "attitude_ref", "terminal_factor"):
        if key not in w:
            raise TuneError(f"{path}: key 'controller.weights.follower.{key}': missing")
    return w


def scaled(w, f):
    out = dict(w)
    p = list(w["position"])
    out["position"] = [p[0] * f["position_xy"], p[1] * f["position_xy"], p[2] * f["position_z"]]
    out["velocity"] = [v * f["velocity"] for v in w["velocity"]]
    for key in ("attitude_ref", "thrust", "terminal_factor"):
        out[key] = w[key] * f[key]
    return out


class Evaluator:
    """Flies scenarios with given factors through `fnmpc campaign`; results cached by folder."""

    def __init__(self, args):
        self.args = args
        self.flights = 0

    def fly(self, label, path, doc, factors, seed, runs):
        d = dict(doc)
        d["controller"] = dict(doc.get("controller") or {})
        d["controller"]["weights"] = dict(d["controller"].get("weights") or {})
        d["controller"]["weights"]["follower"] = scaled(follower_weights(doc, path), factors)
        folder = os.path.join(self.args.out, "trials", label)
        os.makedirs(folder, exist_ok=True)
        scenario = os.path.join(folder, "scenario.yaml")
        with open(scenario, "w") as f:
            yaml.safe_dump(d, f, sort_keys=False)
        campaign = {"scenario": "scenario.yaml", "runs": runs, "seed": seed,
                    "shards": min(runs, max(1, os.cpu_count() or 1)),
                    "out": "campaign", "run": {"timing": "off"}}
        if self.args.duration:
            campaign["run"]["duration"] = self.args.duration
        with open(os.path.join(folder, "campaign.yaml"), "w") as f:
            yaml.safe_dump(campaign, f, sort_keys=False)
        merged = os.path.join(folder, "campaign", "merged", "summary.json")
        if not os.path.exists(merged):  # a resumed study does not fly a finished evaluation
            cmd = [self.args.fnmpc, "campaign", os.path.join(folder, "campaign.yaml"),
                   "--executor", self.args.executor, "-q"]
            rc = subprocess.run(cmd, stdout=subprocess.DEVNULL).returncode
            if rc in (128 + signal.SIGINT, 128 + signal.SIGTERM, -signal.SIGINT, -signal.SIGTERM):
                raise KeyboardInterrupt
            if rc not in (0, 3):
                raise TuneError(f"{' '.join(cmd)}: exit {rc} (its shards' logs are in "
                                f"{os.path.join(folder, 'campaign')})")
        self.flights += 1
        with open(merged) as f:
            s = json.load(f)
        return {"error": s.get("mean_formation_error_m"), "fallbacks": s.get("fallbacks", 0),
                "failures": len(s.get("failures", [])), "runs": s.get("runs")}


FOLDERS = {}  # scenario path -> its folder name under each evaluation (set by main)


def folder_names(paths):
    """A folder name per scenario path: the file name without .yaml, unique among `paths`;
    scenarios of the same file name in different folders get their path's digest appended
    (stable across reruns, so that a resumed study finds its evaluations)."""
    stem = {p: os.path.splitext(os.path.basename(p))[0] for p in paths}
    names = {}
    for p in paths:
        same = [q for q in paths if stem[q] == stem[p] and os.path.abspath(q) != os.path.abspath(p)]
        digest = hashlib.sha256(os.path.abspath(p).encode()).hexdigest()[:8]
        names[p] = f"{stem[p]}-{digest}" if same else stem[p]
    return names


def shown(path):
    """The scenario as progress lines name it: its file name, or its path when another
    scenario has the same file name."""
    stem = os.path.splitext(os.path.basename(path))[0]
    return os.path.basename(path) if FOLDERS.get(path, stem) == stem else path


def evaluate(ev, label, scenarios, factors, seed, runs):
    """Flies `scenarios` [(path, doc)] with `factors`; results keyed by scenario path."""
    results = {}
    for path, doc in scenarios:
        name = FOLDERS.get(path) or os.path.splitext(os.path.basename(path))[0]
        results[path] = ev.fly(f"{label}/{name}", path, doc, factors, seed, runs)
    errors = [r["error"] for r in results.values()]
    mean = (sum(errors) / len(errors)) if all(e is not None for e in errors) else math.inf
    return mean, results


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenarios", nargs="+", help="tuning scenarios")
    p.add_argument("--fnmpc", required=True, help="the fnmpc executable")
    p.add_argument("--trials", type=int, required=True, help="Optuna trials (>= 2; trial 0: defaults)")
    p.add_argument("--held-out", nargs="+", required=True, help="scenarios scored after tuning only")
    p.add_argument("--seeds", type=int, default=3, help="runs per tuning scenario and trial")
    p.add_argument("--held-out-seeds", type=int, default=10, help="runs per held-out scenario")
    p.add_argument("--executor", default="local", choices=["local", "slurm", "dask"])
    p.add_argument("--storage", default="", help="Optuna storage URL (default sqlite:///OUT/tune.db)")
    p.add_argument("--study", default="fnmpc-tune", help="study name in the storage")
    p.add_argument("--duration", type=float, default=0.0, help="fly every scenario this long [s]")
    p.add_argument("-o", "--out", default="tune", help="output folder")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.add_argument("--effective-weights", default="",
                   help="JSON {scenario: {key: value}} of the follower weights each flies with")
    args = p.parse_args(argv)
    if args.effective_weights:
        with open(args.effective_weights) as f:
            EFFECTIVE.update(json.load(f))
    for name, value, low in (("--trials", args.trials, 2), ("--seeds", args.seeds, 1),
                             ("--held-out-seeds", args.held_out_seeds, 1)):
        if value < low or value > 10000:
            raise TuneError(f"{name} {value}: must be in [{low}, 10000]")
    overlap = {os.path.abspath(s) for s in args.scenarios} & {os.path.abspath(s) for s in args.held_out}
    if overlap:
        raise TuneError(f"held-out scenarios must not be tuned on: {', '.join(sorted(overlap))}")
    for group, name in ((args.scenarios, "tuning"), (args.held_out, "held-out")):
        seen = set()
        for s in group:
            if os.path.abspath(s) in seen:
                raise TuneError(f"{s}: given twice as a {name} scenario")
            seen.add(os.path.abspath(s))
    FOLDERS.update(folder_names(args.scenarios + args.held_out))
    try:
        import optuna
    except ImportError as e:
        raise TuneError("Optuna is missing: apt-get install python3-optuna "
                        "(scripts/install-deps.sh)") from e
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    tuning = [(s, load_scenario(s)) for s in args.scenarios]
    held_out = [(s, load_scenario(s)) for s in args.held_out]
    for path, doc in tuning + held_out:
        follower_weights(doc, path)
    storage = args.storage or "sqlite:///" + os.path.join(args.out, "tune.db")
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        study = optuna.create_study(study_name=args.study, storage=storage,
                                    direction="minimize",
                                    sampler=optuna.samplers.TPESampler(seed=1),
                                    load_if_exists=True)
    except Exception as e:  # noqa: BLE001 -- SQLAlchemy's and Optuna's errors vary by URL
        what = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise TuneError(f"{'--storage' if args.storage else '-o (its tune.db)'} {storage}: "
                        f"cannot open the Optuna storage: {what}") from None
    if not study.trials:
        study.enqueue_trial({k: 1.0 for k in FACTORS})  # trial 0: the scenario's own weights
    ev = Evaluator(args)
    start = time.monotonic()
    baseline = {}

    def objective(trial):
        f = {k: trial.suggest_float(k, LOW, HIGH, log=True) for k in FACTORS}
        mean, results = evaluate(ev, f"{args.study}/trial-{trial.number:03d}", tuning, f,
                                 TUNING_SEED, args.seeds)
        fallbacks = sum(r["fallbacks"] or 0 for r in results.values())
        failures = sum(r["failures"] for r in results.values())
        if not baseline:
            baseline.update(fallbacks=fallbacks)
        feasible = math.isfinite(mean) and failures == 0 and fallbacks <= baseline["fallbacks"]
        trial.set_user_attr("mean_formation_error_m", mean if math.isfinite(mean) else None)
        trial.set_user_attr("fallbacks", fallbacks)
        trial.set_user_attr("failures", failures)
        trial.set_user_attr("feasible", feasible)
        score = mean if feasible else (mean * INFEASIBLE if math.isfinite(mean) else 1e3)
        return score

    def progress(study, trial):
        if args.quiet:
            return
        done = len([t for t in study.trials if t.state.is_finished()])
        elapsed = time.monotonic() - start
        eta = elapsed / max(1, trial.number + 1 - first) * (args.trials - done)
        best = study.best_value if study.best_trial else math.nan
        print(f"fnmpc tune: trial {done}/{args.trials}: {trial.value:.4f} m "
              f"({'feasible' if trial.user_attrs.get('feasible') else 'infeasible'}, fallbacks "
              f"{trial.user_attrs.get('fallbacks')}), best {best:.4f} m, ETA {eta / 60:.1f} min",
              file=sys.stderr, flush=True)

    first = len(study.trials)
    # The defaults' fallbacks decide feasibility; a resumed study reads them from trial 0.
    zero = [t for t in study.trials if t.number == 0 and t.state.is_finished()]
    if zero:
        baseline["fallbacks"] = zero[0].user_attrs["fallbacks"]
    remaining = args.trials - len([t for t in study.trials if t.state.is_finished()])
    if remaining > 0:
        study.optimize(objective, n_trials=remaining, callbacks=[progress])
    feasible = [t for t in study.trials if t.state.is_finished() and t.user_attrs.get("feasible")]
    if not feasible:
        raise TuneError("no feasible trial: even the defaults (trial 0) had a failed vehicle on "
                        "the tuning scenarios (see OUT/trials)")
    best = min(feasible, key=lambda t: t.value)
    defaults = {k: 1.0 for k in FACTORS}
    # Held-out scenarios: defaults and the best weights, on seeds no trial flew.
    table = []
    for path, doc in held_out:
        _, d = evaluate(ev, f"{args.study}/held-out/default", [(path, doc)], defaults, HELD_OUT_SEED,
                        args.held_out_seeds)
        _, t = evaluate(ev, f"{args.study}/held-out/tuned-{best.number:03d}", [(path, doc)], best.params,
                        HELD_OUT_SEED, args.held_out_seeds)
        d, t = d[path], t[path]
        change = (t["error"] - d["error"]) / d["error"] if d["error"] and t["error"] is not None else None
        table.append({"scenario": path, "seeds": args.held_out_seeds, "default": d, "tuned": t,
                      "change": change})
    weights = {path: scaled(follower_weights(doc, path), best.params) for path, doc in tuning}
    report = {
        "trials": [{"number": t.number, "value": t.value, "params": t.params, **t.user_attrs}
                   for t in study.trials if t.state.is_finished()],
        "best": {"number": best.number, "factors": best.params, "value": best.value},
        "tuning_scenarios": args.scenarios, "seeds": args.seeds, "first_seed": TUNING_SEED,
        "held_out": table, "held_out_first_seed": HELD_OUT_SEED, "storage": storage,
        "study": args.study,
    }
    with open(os.path.join(args.out, "tune.json"), "w") as f:
        json.dump(report, f, indent=2)
    first_weights = next(iter(weights.values()))
    with open(os.path.join(args.out, "tuned-weights.yaml"), "w") as f:
        f.write(f"# fnmpc tune: best trial {best.number} of {args.study} (factors "
                + ", ".join(f"{k} {v:.3f}" for k, v in best.params.items())
                + f") on the weights of {os.path.basename(tuning[0][0])}\n")
        yaml.safe_dump({"controller": {"weights": {"follower": first_weights}}}, f)
    plot_history(report, os.path.join(args.out, "history.png"))
    ok = True
    for row in table:
        d, t = row["default"], row["tuned"]
        better = row["change"] is not None and row["change"] <= 0.0
        no_more_fallbacks = (t["fallbacks"] or 0) <= (d["fallbacks"] or 0) and t["failures"] == 0
        ok = ok and better and no_more_fallbacks
        print(f"{os.path.basename(row['scenario'])}: default {d['error']:.4f} m "
              f"(fallbacks {d['fallbacks']:.0f}), tuned {t['error']:.4f} m (fallbacks "
              f"{t['fallbacks']:.0f}): {100 * row['change']:+.1f} % over {row['seeds']} seeds",
              file=sys.stderr)
    print(args.out)
    return 0 if ok else 3


def plot_history(report, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    trials = report["trials"]
    xs = [t["number"] for t in trials]
    ys = [t.get("mean_formation_error_m") for t in trials]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.scatter([x for x, t in zip(xs, trials) if t.get("feasible")],
               [y for y, t in zip(ys, trials) if t.get("feasible")], s=14, label="feasible")
    ax.scatter([x for x, t, y in zip(xs, trials, ys) if not t.get("feasible") and y is not None],
               [y for y, t in zip(ys, trials) if not t.get("feasible") and y is not None],
               s=14, marker="x", label="more fallbacks / failure")
    best, curve = math.inf, []
    for t in trials:
        if t.get("feasible") and t["mean_formation_error_m"] is not None:
            best = min(best, t["mean_formation_error_m"])
        curve.append(best)
    ax.step(xs, curve, where="post", color="k", lw=1, label="best so far")
    ax.set_yscale("log")  # an unstable trial is orders of magnitude off
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax.set_xlabel("trial (0: defaults)")
    ax.set_ylabel("mean formation error [m]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    try:
        sys.exit(main())
    except TuneError as e:
        print(f"fnmpc tune: error: {e}", file=sys.stderr)
        sys.exit(1)
    except OSError as e:  # an output that cannot be written (full disk, no permission)
        print(f"fnmpc tune: error: {e.filename if e.filename is not None else '-o'}: "
              f"{e.strerror or e}", file=sys.stderr)
        sys.exit(1)
    except KeyboardInterrupt:
        print("fnmpc tune: stopped; rerun the same command to continue the study",
              file=sys.stderr)
        sys.exit(130)
