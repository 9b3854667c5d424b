# SPDX-License-Identifier: BSD-3-Clause
"""tools/report_headline.py: the verdict and the headline of report.html from summary.json
dictionaries shaped as `fnmpc run` writes them (docs/failure.md)."""
import os
import sys

sys.path.insert(0, os.path.join(os.environ.get("FNMPC_SOURCE_DIR", "."), "tools"))
import report_headline as rh  # noqa: E402

PASSED = {"scenario": "triangle", "complete": True, "failures": [], "landed_safely": True,
          "runs": 1, "steady_state_formation_error_m": 0.0296, "mean_formation_error_m": 0.0491,
          "max_formation_error_m": 0.133, "solver_time_median_s": 2.36e-05,
          "solver_time_max_s": 0.00026, "min_separation_m": 2.24}


def test_passed_run_shows_the_reference_beside_its_figures():
    assert rh.verdict(PASSED)[0] == "passed"
    page = rh.headline_html(PASSED)
    assert "PASSED" in page
    assert "reference work (Sec. 3.3, simulated)" in page
    # The triangle's steady state beside the reference's 0.05 m.
    assert "<td>0.0296 m</td><td>0.05 m</td>" in page
    assert "<td>0.0236 ms</td>" in page
    assert "Failures" not in page


def test_failures_are_listed_and_fail_the_verdict():
    s = dict(PASSED, failures=[
        {"kind": "failsafe", "reason": "failsafe at t = 1.80 s (estimate_unusable)",
         "run": "run-01", "time_s": 1.8, "vehicle": "leader"},
        {"kind": "collision", "reason": "closest 0.2 m", "run": "run-02", "time_s": 3.0,
         "vehicles": ["a", "b"]}])
    assert rh.verdict(s)[0] == "failed"
    page = rh.headline_html(s)
    assert "FAILED" in page and "2 failure(s)" in page
    assert "<td>leader</td><td>failsafe</td><td>1.80</td>" in page
    assert "<td>a / b</td><td>collision</td>" in page


def test_incomplete_run_and_unknown_scenario():
    s = dict(PASSED, complete=False, scenario="my-own", error="unstable at t = 4.0 s")
    word, sentence = rh.verdict(s)
    assert word == "incomplete" and "unstable at t = 4.0 s" in sentence
    page = rh.headline_html(s)
    assert "reference work" not in page  # not one of the reference's experiments


def test_missing_figure_is_not_a_number():
    s = dict(PASSED)
    del s["solver_time_median_s"]
    assert "<th align=left>solver time, median</th><td>n/a</td>" in rh.headline_html(s)


def test_html_in_a_reason_is_escaped():
    s = dict(PASSED, failures=[{"kind": "x", "reason": "<script>", "run": "r", "vehicle": "v"}])
    page = rh.headline_html(s)
    assert "<script>" not in page and "&lt;script&gt;" in page
