# SPDX-License-Identifier: BSD-3-Clause
"""`fnmpc tune` (tools/tune.py, docs/tuning.md): a small real study with Optuna
and the local executor: trial 0 is the defaults, the report, the tuned weights and the plot
are written, the held-out scenario is flown with both weight sets on seeds no trial used, a
rerun continues the study without flying finished evaluations again, and bad input is refused
naming the file and key (a
scenario without follower weights is tuned from the struct's defaults, as it flies)."""
import json
import os
import subprocess
import sys

import pytest
import yaml

FNMPC = os.environ["FNMPC"]
SOURCE = os.environ["FNMPC_SOURCE_DIR"]
TRIANGLE = os.path.join(SOURCE, "config/scenarios/triangle.yaml")
HELD_OUT = os.path.join(SOURCE, "config/scenarios/flying-leader-paper.yaml")


def tune(out, *extra, trials=2):
    return subprocess.run(
        [FNMPC, "tune", TRIANGLE, "--held-out", HELD_OUT, "--trials", str(trials), "--seeds", "1",
         "--held-out-seeds", "1", "--duration", "26", "-o", str(out), *extra],
        capture_output=True, text=True, timeout=1200)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("tune")
    r = tune(out)
    return out, r


def test_a_study_writes_its_report_weights_and_plot(study):
    out, r = study
    assert r.returncode in (0, 3), r.stderr
    assert r.stdout.strip() == str(out)
    report = json.load(open(out / "tune.json"))
    trials = report["trials"]
    assert [t["number"] for t in trials] == [0, 1]
    assert all(v == 1.0 for v in trials[0]["params"].values())  # trial 0: the defaults
    assert any(v != 1.0 for v in trials[1]["params"].values())  # then Optuna's proposal
    for t in trials:
        assert t["mean_formation_error_m"] > 0.0
        assert t["fallbacks"] >= 0
    assert report["best"]["number"] in (0, 1)
    (row,) = report["held_out"]
    assert row["seeds"] == 1
    assert row["default"]["runs"] == 1 and row["tuned"]["runs"] == 1
    assert report["held_out_first_seed"] != report["first_seed"]
    # the progress lines and the held-out verdict
    assert "trial 2/2" in r.stderr
    assert "flying-leader-paper.yaml: default" in r.stderr
    # the tuned weights are the triangle's scaled by the best factors and fly as a scenario
    w = yaml.safe_load(open(out / "tuned-weights.yaml"))["controller"]["weights"]["follower"]
    base = yaml.safe_load(open(TRIANGLE))["controller"]["weights"]["follower"]
    f = report["best"]["factors"]
    assert w["thrust"] == pytest.approx(base["thrust"] * f["thrust"])
    assert w["position"][2] == pytest.approx(base["position"][2] * f["position_z"])
    s = yaml.safe_load(open(TRIANGLE))
    s["controller"]["weights"]["follower"] = w
    for k in ("vehicle_file", "sensors_file"):
        s[k] = os.path.join(SOURCE, "config/scenarios", s[k])
    tuned = out / "tuned.yaml"
    yaml.safe_dump(s, open(tuned, "w"))
    dry = subprocess.run([FNMPC, "run", str(tuned), "--dry-run"], capture_output=True, text=True)
    assert dry.returncode == 0, dry.stderr
    assert (out / "history.png").stat().st_size > 1000
    assert (out / "tune.db").exists()  # the default SQLite storage


def test_a_rerun_continues_the_study_without_flying_finished_evaluations(study):
    out, _ = study
    merged = out / "trials/fnmpc-tune/trial-000/triangle/campaign/merged/summary.json"
    before = merged.stat().st_mtime_ns
    r = tune(out, trials=3)
    assert r.returncode in (0, 3), r.stderr
    trials = json.load(open(out / "tune.json"))["trials"]
    assert [t["number"] for t in trials] == [0, 1, 2]
    assert merged.stat().st_mtime_ns == before
    assert "trial 3/3" in r.stderr and "trial 1/3" not in r.stderr


def test_bad_input_is_refused_naming_it(tmp_path):
    r = subprocess.run(
        [FNMPC, "tune", TRIANGLE, "--held-out", TRIANGLE, "--trials", "2", "-o", str(tmp_path)],
        capture_output=True, text=True)
    assert r.returncode == 1
    assert "held-out scenarios must not be tuned on" in r.stderr
    # every scenario is checked by fnmpc's own reader before anything flies
    text = open(TRIANGLE).read().replace("thrust: 0.05, attitude_ref", "thrust: -1, attitude_ref")
    text = text.replace("../vehicles/", os.path.join(SOURCE, "config/vehicles") + "/")
    text = text.replace("../sensors/", os.path.join(SOURCE, "config/sensors") + "/")
    bad = tmp_path / "bad-weight.yaml"
    bad.write_text(text)
    r = subprocess.run([FNMPC, "tune", str(bad), "--held-out", HELD_OUT, "--trials", "2",
                        "-o", str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 1
    assert f"{bad}:" in r.stderr and "thrust" in r.stderr, r.stderr
    assert not (tmp_path / "o" / "trials").exists()
    r = subprocess.run([FNMPC, "tune", TRIANGLE, "--held-out", HELD_OUT, "--trials", "1"],
                       capture_output=True, text=True)
    assert r.returncode == 2  # CLI range: at least the defaults and one proposal


def test_a_bad_storage_is_one_line_naming_the_flag(tmp_path):
    for storage, what in (("bogus://", "Can't load plugin"),
                          ("sqlite:////proc/fnmpc-forbidden/tune.db", "unable to open")):
        out = tmp_path / storage.split(":")[0]
        r = subprocess.run([FNMPC, "tune", TRIANGLE, "--held-out", HELD_OUT, "--trials", "2",
                            "--storage", storage, "-o", str(out)],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 1, r.stderr
        assert (f"fnmpc tune: error: --storage {storage}: cannot open the Optuna storage: "
                in r.stderr), r.stderr
        assert what in r.stderr, r.stderr
        assert "Traceback" not in r.stderr
        assert not (out / "trials").exists()


def test_a_scenario_that_is_not_utf8_is_refused_naming_file_and_line(tmp_path):
    text = open(TRIANGLE, "rb").read().replace(b"name: triangle", b"name: tri\xe1ngulo", 1)
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes(text)
    r = subprocess.run([FNMPC, "tune", str(bad), "--held-out", HELD_OUT, "--trials", "2",
                        "-o", str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 1, r.stderr
    line = text[:text.index(b"\xe1")].count(b"\n") + 1
    assert f"{bad}:{line}:" in r.stderr and "'name'" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    # the driver itself, given such a file directly, says the same in one line
    sys.path.insert(0, os.path.join(SOURCE, "tools"))
    import tune as tool
    with pytest.raises(tool.TuneError, match=f"{bad}: key '\\(top level\\)': not valid UTF-8"):
        tool.load_scenario(str(bad))


def test_scenarios_are_told_apart_by_path_not_file_name(tmp_path):
    # two scenarios of the same file name in different folders: two folder names, both flown
    sys.path.insert(0, os.path.join(SOURCE, "tools"))
    import tune as tool
    a, b = str(tmp_path / "a" / "triangle.yaml"), str(tmp_path / "b" / "triangle.yaml")
    other = HELD_OUT
    names = tool.folder_names([a, b, other])
    assert names[other] == "flying-leader-paper"  # a file name that occurs once keeps it
    assert names[a] != names[b] and names[a].startswith("triangle-"), names
    assert tool.folder_names([a, b, other]) == names  # stable: a rerun finds its folders

    class Recorder:
        def __init__(self):
            self.labels = []

        def fly(self, label, path, doc, factors, seed, runs):
            self.labels.append(label)
            return {"error": 1.0 if path == a else 3.0, "fallbacks": 0, "failures": 0, "runs": 1}

    tool.FOLDERS.update(names)
    ev = Recorder()
    mean, results = tool.evaluate(ev, "trial-000", [(a, {}), (b, {})], {}, 1000, 1)
    assert set(results) == {a, b}
    assert len(set(ev.labels)) == 2, ev.labels
    assert mean == 2.0  # both scenarios count
    assert tool.shown(a) == a and tool.shown(other) == "flying-leader-paper.yaml"


def test_a_folder_tune_did_not_make_is_refused_and_kept(tmp_path):
    (tmp_path / "notes.md").write_text("mine\n")
    r = subprocess.run([FNMPC, "tune", TRIANGLE, "--held-out", HELD_OUT, "--trials", "2",
                        "-o", str(tmp_path)], capture_output=True, text=True)
    assert r.returncode == 1
    assert ".fnmpc-tune" in r.stderr, r.stderr
    assert sorted(os.listdir(tmp_path)) == ["notes.md"]
