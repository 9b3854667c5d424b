# SPDX-License-Identifier: BSD-3-Clause
"""Closed-loop runs from Python against the CLI: the triangle flown by fnmpc.run() and by
`fnmpc run` with the same seed gives the same summary.json figures and the same logs
(except wall-clock solver timings).

Same, not bit-identical: each process is deterministic, but the extension module and the
executable are two links of the library and their summary figures differ in the 11th to
12th significant digit (measured: relative 2e-11 at most on this triangle). The figures the
CLI prints (its result line) and the CSV logs (5 decimals) are equal."""
import json
import os
import subprocess

import numpy as np
import pytest

import fnmpc

DURATION = 30.0  # s: take-off, one leg of the leader, landing (--duration shortens)
SEED = 2
# Figures measured with the wall clock: they differ between any two runs.
TIMING_KEYS = ("solver_time", "over_budget")
TIMING_COLUMNS = ("solver_time",)


RELATIVE = 1e-9  # summary figures: 100 times the largest relative difference measured


def numbers_match(a, b, path=""):
    """Same structure, same ints, bools and strings, floats within RELATIVE."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            numbers_match(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            numbers_match(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=RELATIVE, abs=1e-300), path
    else:
        assert a == b and type(a) is type(b), path


def printed(s):
    """The CLI's result line of a run (fnmpc/experiment/run_folder.cpp)."""
    return (f"{s['steady_state_formation_error_m']:.4f} {s['max_formation_error_m']:.3f} "
            f"{s['fallbacks']} {s['landed_safely']}")


def without_timing(x):
    if isinstance(x, dict):
        return {k: without_timing(v) for k, v in x.items()
                if not any(t in k for t in TIMING_KEYS) and k != "scenario_file"}
    if isinstance(x, list):
        return [without_timing(v) for v in x]
    return x


@pytest.fixture(scope="module")
def runs(tmp_path_factory, request):
    from conftest import SOURCE_DIR, fnmpc_exe
    exe = fnmpc_exe()
    scenario = os.path.join(SOURCE_DIR, "config", "scenarios", "triangle.yaml")
    base = tmp_path_factory.mktemp("runs")
    cli_dir = base / "cli"
    subprocess.run([exe, "run", scenario, "--duration", str(DURATION), "--seed", str(SEED),
                    "-q", "-o", str(cli_dir)], check=True)
    result = fnmpc.run(scenario, seed=SEED, duration=DURATION, out=base / "py")
    return cli_dir, result


def test_summary_matches_cli(runs):
    cli_dir, result = runs
    with open(cli_dir / "summary.json") as f:
        cli = json.load(f)
    with open(os.path.join(result.dir, "summary.json")) as f:
        written = json.load(f)
    assert written == result.summary
    numbers_match(without_timing(result.summary), without_timing(cli))
    for key in ("steady_state_formation_error_m", "max_formation_error_m", "min_separation_m"):
        assert isinstance(cli[key], float)  # the headline figures are covered
    assert printed(result.summary["run_summaries"][0]) == printed(cli["run_summaries"][0])
    assert result.summary["run_summaries"][0]["seed"] == SEED


def test_logs_match_cli(runs):
    cli_dir, result = runs
    assert len(result.logs) == 1
    logs = result.logs[0]
    assert set(logs) == {"leader", "follower1", "follower2"}
    for name, log in logs.items():
        cli = fnmpc.read_log(str(cli_dir / "run-01" / f"{name}.csv"))
        assert log.dtype.names == cli.dtype.names
        assert len(log) > DURATION / 0.05 * 0.9
        assert np.all(np.diff(log["t"]) > 0)
        for col in log.dtype.names:
            if col in TIMING_COLUMNS:
                continue
            if log[col].dtype.kind == "f":  # the logs' 5 decimals, one last-digit flip allowed
                np.testing.assert_allclose(log[col], cli[col], rtol=0, atol=1.5e-5,
                                           err_msg=f"{name}.{col}")
            else:
                assert list(log[col]) == list(cli[col]), f"{name}.{col}"
    phases = set(logs["follower1"]["phase"])
    assert {"takeoff", "nmpc", "landing"} <= phases


def test_run_with_scenario_object_and_temp_folder(triangle):
    sc = fnmpc.load_scenario(triangle).shortened(26.0)
    result = fnmpc.run(sc, runs=2, seed=5)
    assert result.dir is None
    assert result.summary["runs"] == 2
    assert [r["seed"] for r in result.summary["run_summaries"]] == [5, 6]
    assert len(result.logs) == 2
    a, b = result.logs[0]["follower1"], result.logs[1]["follower1"]
    assert not np.array_equal(a["est_x"], b["est_x"])  # other sensor noise


def test_run_rejects_bad_arguments(triangle):
    with pytest.raises(ValueError):
        fnmpc.run(triangle, runs=0)
    with pytest.raises(fnmpc.ConfigError):
        fnmpc.run("/nonexistent.yaml")
