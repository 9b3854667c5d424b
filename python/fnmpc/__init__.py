# SPDX-License-Identifier: BSD-3-Clause
"""fnmpc: decentralized NMPC of multi-rotor formations, from Python.

The compiled core (``fnmpc._fnmpc``) binds the C++ library: configuration files
(:func:`load_vehicle`, :func:`load_sensors`, :func:`load_scenario`), the shipped optimal
control problems (:class:`LeaderOcp`, :class:`FollowerOcp`, :class:`ReducedFollowerOcp`),
the simulator (:class:`World`) and closed-loop runs (:func:`run`). See docs/python.md.
"""
from __future__ import annotations

import dataclasses
import json
import os
import shutil
import tempfile
from typing import Dict, List, Optional, Union

import numpy as np

from ._fnmpc import *  # noqa: F401,F403
from ._fnmpc import ConfigError, Scenario, _run_folder, load_scenario

__all__ = [name for name in dir() if not name.startswith("_")] + ["run", "RunResult",
                                                                    "read_log"]


@dataclasses.dataclass
class RunResult:
    """What :func:`run` returns.

    summary: summary.json of the run folder as a dict (the aggregate over the runs, with
        ``run_summaries``: one summary per run).
    logs: one dict per run, vehicle name -> numpy structured array of its CSV log (one field
        per column of docs/data-formats.md; ``phase`` and the other words as strings).
    dir: the run folder (None when run() wrote to a temporary folder it removed).
    """

    summary: dict
    logs: List[Dict[str, np.ndarray]]
    dir: Optional[str]


def read_log(path: str) -> np.ndarray:
    """Reads one vehicle's CSV log of a run folder into a numpy structured array."""
    return np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8",
                         deletechars="")


def run(scenario: Union[str, os.PathLike, Scenario], runs: int = 1, seed: Optional[int] = None,
        out: Optional[Union[str, os.PathLike]] = None, duration: Optional[float] = None,
        downwash: Optional[bool] = None, progress: bool = False) -> RunResult:
    """Runs a scenario in closed loop, exactly as ``fnmpc run`` does.

    scenario: a scenario file or a :class:`Scenario` (as loaded, possibly changed).
    runs: number of runs, with seeds seed, seed + 1, ...
    seed: first noise seed (default: the scenario's).
    out: run folder to write (default: a temporary folder, removed after reading the logs).
    duration: shorten the scenario to this simulated time [s] (``--duration``).
    downwash: override the scenario's wake model switch (``--downwash on|off``).
    """
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    sc = load_scenario(os.fspath(scenario)) if not isinstance(scenario, Scenario) else scenario
    if duration is not None:
        sc = sc.shortened(float(duration))
    if downwash is not None:
        sc.downwash = bool(downwash)
    folder = os.fspath(out) if out is not None else tempfile.mkdtemp(prefix="fnmpc-run-")
    try:
        summary = json.loads(_run_folder(sc, folder, runs, -1 if seed is None else int(seed),
                                         progress))
        logs = []
        for r in summary["run_summaries"]:
            run_dir = os.path.join(folder, r["dir"])
            logs.append({v.name: read_log(os.path.join(run_dir, v.name + ".csv"))
                         for v in sc.vehicles})
    finally:
        if out is None:
            shutil.rmtree(folder, ignore_errors=True)
    return RunResult(summary=summary, logs=logs, dir=folder if out is not None else None)
