# SPDX-License-Identifier: BSD-3-Clause
"""`fnmpc campaign` (tools/campaign.py, docs/campaigns.md): the campaign file's errors carry
file, line and key; every executor (a local process pool, a real single-node Slurm started by
scripts/slurm-local.sh, a dask.distributed LocalCluster) merges into the folder the unsharded
`fnmpc run` writes, byte for byte; a rerun resumes (complete shards skipped, complete runs
kept); Ctrl-C / SIGTERM cancel (no process left, no merge, 130 / 143); a failed shard is named
with its exit code and seeds and nothing is merged.

Environment: FNMPC (the fnmpc executable), FNMPC_SOURCE_DIR (the source tree); ctest sets
both (tests/campaign/CMakeLists.txt). The triangle flies 25 s with --timing off, 4 runs."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

FNMPC = os.environ["FNMPC"]
SOURCE = os.environ["FNMPC_SOURCE_DIR"]
DRIVER = os.path.join(SOURCE, "tools", "campaign.py")
TRIANGLE = os.path.join(SOURCE, "config", "scenarios", "triangle.yaml")
PY = "/usr/bin/python3"


def write_campaign(folder, name="c.yaml", runs=4, shards=2, extra=""):
    path = os.path.join(folder, name)
    with open(path, "w") as f:
        f.write(f"scenario: {TRIANGLE}\nruns: {runs}\nshards: {shards}\n"
                f"run: {{duration: 25, timing: off}}\nout: out\n{extra}")
    return path


def campaign_cmd(path, executor, *extra):
    return [FNMPC, "campaign", path, "--executor", executor, "--script", DRIVER, *extra]


def run(cmd, env=None, timeout=900):
    t0 = time.monotonic()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    r.seconds = time.monotonic() - t0
    sys.stderr.write(f"{' '.join(cmd[:4])}...: exit {r.returncode} in {r.seconds:.1f} s\n")
    return r


def record(out):
    with open(os.path.join(out, "campaign.json")) as f:
        return json.load(f)


def same_tree(a, b):
    r = subprocess.run(["diff", "-r", str(a), str(b)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[:2000] + r.stderr
    return True


def processes_with(text):
    """PIDs of processes whose command line holds `text` (our shards' output folder)."""
    pids = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmdline = f.read().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if text in cmdline and "fnmpc" in cmdline and " run " in cmdline:
            pids.append(int(pid))
    return pids


def wait_for(predicate, timeout, what, proc=None):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if predicate():
            return time.monotonic() - t0
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"exit {proc.returncode} before {what}: {proc.stderr.read()}")
        time.sleep(0.2)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def complete_runs(out):
    n = 0
    shards = os.path.join(out, "shards")
    for shard in os.listdir(shards) if os.path.isdir(shards) else []:
        for d in os.listdir(os.path.join(shards, shard)):
            p = os.path.join(shards, shard, d, "summary.json")
            if d.startswith("run-") and os.path.exists(p):
                try:
                    with open(p) as f:
                        n += json.load(f).get("complete") is True
                except ValueError:
                    pass
    return n


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The unsharded run the merged folders must equal."""
    out = tmp_path_factory.mktemp("reference") / "ref"
    r = run([FNMPC, "run", TRIANGLE, "--runs", "4", "--timing", "off", "--duration", "25",
             "--jobs", "2", "-q", "-o", str(out)])
    assert r.returncode == 0, r.stderr
    return out


# ---------------------------------------------------------------------------------------------
# The campaign file

BAD_FILES = [
    ("runs: 4\n", 1, "scenario", "required"),
    ("scenario: {s}\n", 1, "runs", "required"),
    ("scenario: {s}\nruns: 0\n", 2, "runs", "must be an integer in 1..10000"),
    ("scenario: {s}\nruns: 2\nshards: 3\n", 3, "shards", "must be at most runs (2)"),
    ("scenario: {s}\nruns: 2\nseed: -1\n", 3, "seed", "must be an integer"),
    ("scenario: nowhere.yaml\nruns: 2\n", 1, "scenario", "no such file"),
    ("scenario: {s}\nruns: 2\nrun:\n  reality: on\n  duraton: 25\n", 5, "run.duraton",
     "unknown key"),
    ("scenario: {s}\nruns: 2\nrun:\n  duration: -3\n", 4, "run.duration", "> 0"),
    ("scenario: {s}\nruns: 2\nrun: {{compensation: magic}}\n", 3, "run.compensation",
     "must be one of none, observer, wake, cooperative"),
    ("scenario: {s}\nruns: 2\nrun: {{timing: maybe}}\n", 3, "run.timing", "must be on or off"),
    ("scenario: {s}\nruns: 2\nslurm:\n  time_limit: 90 minutes\n", 4, "slurm.time_limit",
     "HH:MM:SS"),
    ("scenario: {s}\nruns: 2\nslurm:\n  cpus_per_task: 0\n", 4, "slurm.cpus_per_task",
     "must be an integer"),
    ("scenario: {s}\nruns: 2\nslurm:\n  sbatch_args: --exclusive\n", 4, "slurm.sbatch_args",
     "must be a list of strings"),
    ("scenario: {s}\nruns: 2\ndask: {{scheduler: localhost:8786}}\n", 3, "dask.scheduler",
     "tcp://host:port"),
    ("scenario: {s}\nruns: 2\ndask:\n  workers: two\n", 4, "dask.workers", "must be an integer"),
    ("scenario: {s}\nruns: 2\nexecutor: slurm\n", 3, "executor", "unknown key"),
    ("scenario: {s}\nruns: 2\nruns: 3\n", 3, "runs", "given twice"),
]


@pytest.mark.parametrize("text,line,key,what", BAD_FILES)
def test_a_bad_campaign_file_is_refused_with_file_line_and_key(tmp_path, text, line, key, what):
    path = tmp_path / "bad.yaml"
    path.write_text(text.format(s=TRIANGLE))
    r = run([PY, DRIVER, str(path), "--fnmpc", FNMPC, "-q"])
    assert r.returncode == 1, r.stderr
    assert f"{path}:{line}: key '{key}': " in r.stderr, r.stderr
    assert what in r.stderr, r.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "campaigns").exists()


def test_a_folder_of_another_campaign_is_refused(tmp_path):
    path = write_campaign(str(tmp_path))
    os.makedirs(tmp_path / "out")
    (tmp_path / "out" / "campaign.json").write_text(json.dumps(
        {"experiment": {"scenario": TRIANGLE, "runs": 6, "seed": None, "shards": 2,
                        "run": {"duration": 25.0, "timing": "off"}}}))
    r = run(campaign_cmd(path, "local", "-q"))
    assert r.returncode == 1
    assert "holds another campaign (key 'runs': 6 there, 4 now)" in r.stderr, r.stderr


def test_a_folder_that_is_no_campaign_is_refused_and_kept(tmp_path):
    # a user's folder as -o: refused before anything is written, its files untouched
    path = write_campaign(str(tmp_path))
    os.makedirs(tmp_path / "out" / "src")
    (tmp_path / "out" / "notes.md").write_text("mine\n")
    r = run(campaign_cmd(path, "local", "-q"))
    assert r.returncode == 1
    assert "not empty and not a campaign folder" in r.stderr, r.stderr
    assert sorted(os.listdir(tmp_path / "out")) == ["notes.md", "src"]
    assert "Traceback" not in r.stderr


def test_a_campaign_file_that_is_not_utf8_is_refused_with_file_line_and_key(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes(f"scenario: {TRIANGLE}\nruns: 2\nout: r\xe9sultats\n".encode("latin-1"))
    for cmd in ([PY, DRIVER, str(path), "--fnmpc", FNMPC, "-q"],
                [FNMPC, "campaign", str(path), "--script", DRIVER, "-q"]):
        r = run(cmd)
        assert r.returncode == 1, r.stderr
        assert f"{path}:3: key 'out': not valid UTF-8 (byte 0xe9 at column 7)" in r.stderr, \
            r.stderr
        assert "Traceback" not in r.stderr
    assert sorted(os.listdir(tmp_path)) == ["latin1.yaml"]


def test_an_out_that_cannot_be_made_is_refused_naming_the_key(tmp_path):
    # `out` under /proc (no folder can be made there) from the file, then from -o
    path = write_campaign(str(tmp_path))
    with open(path) as f:
        text = f.read().replace("out: out\n", "out: /proc/fnmpc-forbidden\n")
    with open(path, "w") as f:
        f.write(text)
    r = run(campaign_cmd(path, "local", "-q"))
    assert r.returncode == 1, r.stderr
    assert (f"{path}:5: key 'out': cannot make the campaign folder /proc/fnmpc-forbidden"
            in r.stderr), r.stderr
    assert "Traceback" not in r.stderr
    r = run(campaign_cmd(path, "local", "-q", "-o", "/proc/fnmpc-forbidden-too"))
    assert r.returncode == 1, r.stderr
    assert "-o: cannot make the campaign folder /proc/fnmpc-forbidden-too" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr


# ---------------------------------------------------------------------------------------------
# local

def test_local_merges_to_the_unsharded_run_and_a_rerun_flies_nothing(tmp_path, reference):
    path = write_campaign(str(tmp_path))
    out = tmp_path / "out"
    r = run(campaign_cmd(path, "local"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(out / "merged")
    same_tree(reference, out / "merged")
    rec = record(out)
    assert rec["executor"] == "local" and rec["state"] == "merged" and rec["attempt"] == 1
    assert [s["state"] for s in rec["shards"]] == ["done", "done"]
    assert [s["exit_code"] for s in rec["shards"]] == [0, 0]
    assert [s["seeds"] for s in rec["shards"]] == [[1, 3], [2, 4]]
    assert all(s["duration_s"] > 1 for s in rec["shards"])
    assert rec["merge"]["exit_code"] == 0
    # the progress line: shards, runs and an ETA
    assert "campaign: shards 2/2 done, runs 4/4" in r.stderr and "ETA" in r.stderr
    # the shards' folders and logs where docs/campaigns.md says
    assert sorted(os.listdir(out / "shards")) == ["shard-0", "shard-1"]
    assert (out / "logs" / "shard-1.log").exists()

    csv = out / "shards" / "shard-0" / "run-01" / "follower1.csv"
    mtime = os.stat(csv).st_mtime_ns
    again = run(campaign_cmd(path, "local"))
    assert again.returncode == 0, again.stderr
    assert again.stdout.strip() == str(out / "merged")
    assert "2 of 2 shards complete from an earlier attempt, skipped" in again.stderr
    rec = record(out)
    assert rec["attempt"] == 2
    assert [s["state"] for s in rec["shards"]] == ["skipped", "skipped"]
    assert [s["duration_s"] for s in rec["shards"]] == [None, None]
    assert [s["runs_complete_before"] for s in rec["shards"]] == [2, 2]
    assert os.stat(csv).st_mtime_ns == mtime  # nothing flown again
    assert again.seconds < 15
    same_tree(reference, out / "merged")


def test_local_ctrl_c_stops_every_shard_and_merges_nothing(tmp_path):
    path = write_campaign(str(tmp_path), runs=2, shards=2)
    out = tmp_path / "out"
    p = subprocess.Popen([PY, DRIVER, path, "--executor", "local", "--fnmpc", FNMPC, "-q"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: len(processes_with(str(out))) == 2, 60, "both shards running", p)
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=60)
    assert p.returncode == 130, stderr
    assert stdout == ""
    assert processes_with(str(out)) == []
    assert not (out / "merged").exists()
    rec = record(out)
    assert rec["state"] == "cancelled"
    assert [s["state"] for s in rec["shards"]] == ["cancelled", "cancelled"]
    assert [s["exit_code"] for s in rec["shards"]] == [130, 130]
    assert "rerun the same command to resume" in stderr


def test_a_failed_shard_is_named_with_its_seeds_and_nothing_is_merged(tmp_path):
    # An fnmpc whose shard 1/2 fails as an unstable simulator does (exit 4), the rest real.
    wrapper = tmp_path / "fnmpc-failing"
    wrapper.write_text(f"""#!/bin/bash
for a in "$@"; do [[ $a == 1/2 ]] && {{ echo "simulator unstable (test)" >&2; exit 4; }}; done
exec {FNMPC} "$@"
""")
    wrapper.chmod(0o755)
    # (shard 0 flies its run for real: the failure of one shard is no reason to stop another)
    path = write_campaign(str(tmp_path), runs=2, shards=2, extra="seed: 7\n")
    out = tmp_path / "out"
    r = run([PY, DRIVER, path, "--executor", "local", "--fnmpc", str(wrapper)])
    assert r.returncode == 1, r.stderr
    assert r.stdout == ""
    msg = ("campaign: shard 1/2 failed, exit 4 (simulator unstable); runs not complete: "
           "run-02 (seed 8); log: ")
    assert msg in r.stderr, r.stderr
    assert "1 of 2 shards failed; nothing merged" in r.stderr
    assert not (out / "merged").exists()
    rec = record(out)
    assert rec["state"] == "failed"
    s0, s1 = rec["shards"]
    assert (s0["state"], s0["exit_code"], s0["seeds"]) == ("done", 0, [7])
    assert (s1["state"], s1["exit_code"]) == ("failed", 4)
    assert s1["incomplete"] == [{"run": "run-02", "seed": 8}]
    assert "simulator unstable (test)" in (out / "logs" / "shard-1.log").read_text()


# ---------------------------------------------------------------------------------------------
# slurm: a real single-node cluster

@pytest.fixture(scope="module")
def slurm(tmp_path_factory):
    folder = tmp_path_factory.mktemp("slurm") / "cluster"
    script = os.path.join(SOURCE, "scripts", "slurm-local.sh")
    t0 = time.monotonic()
    r = subprocess.run([script, "start", str(folder)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    sys.stderr.write(f"slurm-local.sh start: {time.monotonic() - t0:.1f} s\n")
    (line,) = [x for x in r.stdout.splitlines() if x.startswith("export SLURM_CONF=")]
    env = dict(os.environ, SLURM_CONF=line.split("=", 1)[1])
    try:
        yield env
    finally:
        subprocess.run([script, "stop", str(folder)], capture_output=True, text=True,
                       timeout=120)


def test_slurm_runs_an_array_sigterm_cancels_it_and_a_rerun_resumes(tmp_path, reference,
                                                                    slurm):
    path = write_campaign(str(tmp_path), extra="slurm: {time_limit: \"00:10:00\", "
                                                "cpus_per_task: 1}\n")
    out = tmp_path / "out"
    p = subprocess.Popen([PY, DRIVER, path, "--executor", "slurm", "--fnmpc", FNMPC],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=slurm)
    # SIGTERM once the first run of the campaign is complete: a partial shard to resume
    wait_for(lambda: complete_runs(out) >= 1, 300, "a complete run", p)
    p.send_signal(signal.SIGTERM)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 143, stderr
    assert stdout == ""
    rec = record(out)
    job = rec["slurm"]["job_id"]
    assert rec["state"] == "cancelled"
    assert f"submitted Slurm job {job}" in stderr
    q = subprocess.run(["squeue", "-h", "-j", job], capture_output=True, text=True, env=slurm)
    assert q.stdout.strip() == ""
    assert processes_with(str(out)) == []
    assert not (out / "merged").exists()
    script = (out / "slurm" / "array.sh").read_text()
    assert "#SBATCH --array=0-1" in script and "#SBATCH --time=00:10:00" in script
    assert "#SBATCH --cpus-per-task=1" in script

    r = run(campaign_cmd(path, "slurm"), env=slurm)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(out / "merged")
    same_tree(reference, out / "merged")
    rec = record(out)
    assert rec["attempt"] == 2 and rec["executor"] == "slurm"
    assert rec["slurm"]["job_id"] != job
    assert sum(s["runs_complete_before"] for s in rec["shards"]) >= 1  # kept, not flown again
    for s in rec["shards"]:
        if s["state"] == "done":
            assert s["slurm_state"] == "COMPLETED" and s["exit_code"] == 0
        else:
            assert s["state"] == "skipped"
    assert "campaign: shards 2/2 done, runs 4/4" in r.stderr


# ---------------------------------------------------------------------------------------------
# dask: a LocalCluster

def test_dask_cancel_then_a_rerun_merges_to_the_unsharded_run(tmp_path, reference):
    path = write_campaign(str(tmp_path), extra="dask: {workers: 2}\n")
    out = tmp_path / "out"
    p = subprocess.Popen([PY, DRIVER, path, "--executor", "dask", "--fnmpc", FNMPC, "-q"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for(lambda: len(processes_with(str(out))) == 2, 120, "both shards running on workers",
             p)
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 130, stderr
    wait_for(lambda: processes_with(str(out)) == [], 30, "the workers' fnmpc to stop")
    assert not (out / "merged").exists()
    assert record(out)["state"] == "cancelled"

    r = run(campaign_cmd(path, "dask"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(out / "merged")
    same_tree(reference, out / "merged")
    rec = record(out)
    assert rec["executor"] == "dask" and rec["dask"]["scheduler"] == "LocalCluster"
    assert rec["dask"]["workers"] == 2
    assert [s["state"] for s in rec["shards"]] == ["done", "done"]
    assert "campaign: shards 2/2 done, runs 4/4" in r.stderr
