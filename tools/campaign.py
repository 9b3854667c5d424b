#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""The campaign driver behind `fnmpc campaign` (docs/campaigns.md).

    /usr/bin/python3 tools/campaign.py CAMPAIGN.yaml [--executor local|slurm|dask] [-o OUT]
                                       [--fnmpc PATH] [-q]

A campaign is one Monte Carlo experiment (a scenario flown `runs` times with seeds seed,
seed+1, ...) cut into `shards` slices, each `fnmpc run ... --shard I/N --resume`, run on
this machine's cores (local: a pool of subprocesses), a Slurm job array (slurm: sbatch,
squeue/sacct) or a Dask cluster (dask: dask.distributed), and joined with `fnmpc merge`
into the folder the unsharded `fnmpc run` writes. Layout of OUT:

    OUT/shards/shard-I/   the run folder of shard I (`fnmpc run --shard I/N --resume`)
    OUT/logs/shard-I.log  its stdout and stderr
    OUT/slurm/array.sh    (slurm) the job array script; shard-I.rc: each task's exit code
    OUT/merged/           the `fnmpc merge` result, written only when every shard is complete
    OUT/campaign.json     what ran: executor, each shard's state, exit code, duration, job id

Exit codes: 0 merged; 3 merged, but a vehicle failed in a run (as `fnmpc run`); 1 a bad
campaign file (FILE:LINE: key 'x': what), a failed shard (named with its exit code and the
seeds of its runs that did not complete; nothing is merged) or a failed merge; 2 bad
command line; 130 / 143 cancelled by SIGINT / SIGTERM (subprocesses stopped, the Slurm job
cancelled, the Dask futures cancelled). Rerunning the same command resumes: complete shards
are skipped and every shard's `fnmpc run --resume` keeps its complete runs.
"""

import argparse
import datetime
import json
import math
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time

import yaml

EXIT_ERROR = 1
FNMPC_EXIT = {0: "ok", 1: "error", 2: "usage error", 3: "a vehicle failed",
              4: "simulator unstable", 130: "interrupted (SIGINT)", 143: "terminated (SIGTERM)"}


class CampaignError(Exception):
    pass


# --------------------------------------------------------------------------------------------
# The campaign file

RUN_KEYS = ("reality", "compensation", "duration", "timing")
COMPENSATIONS = ("none", "observer", "wake", "cooperative")
MAX_SEED = 2 ** 53


class Parser:
    """Checks a campaign file node by node, so that errors carry the file and line."""

    def __init__(self, path):
        self.path = path
        self.loader = yaml.SafeLoader("")

    def fail(self, node, key, what):
        line = node.start_mark.line + 1 if node is not None else 1
        raise CampaignError(f"{self.path}:{line}: key '{key}': {what}")

    def value(self, node):
        return self.loader.construct_object(node, deep=True)

    def mapping(self, node, key, allowed):
        if not isinstance(node, yaml.MappingNode):
            self.fail(node, key, "must be a mapping (key: value lines)")
        out = {}
        for k, v in node.value:
            if not isinstance(k, yaml.ScalarNode):
                self.fail(k, key, "a key must be a plain name")
            name = k.value
            full = f"{key}.{name}" if key else name
            if name not in allowed:
                self.fail(k, full, f"unknown key (known: {', '.join(allowed)})")
            if name in out:
                self.fail(k, full, "given twice")
            out[name] = (k, v)
        return out

    def integer(self, node, key, lo, hi=None):
        v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
        if not isinstance(v, int) or isinstance(v, bool) or v < lo or (hi is not None and v > hi):
            rng = f">= {lo}" if hi is None else f"in {lo}..{hi}"
            self.fail(node, key, f"must be an integer {rng}, not {self.show(node)}")
        return v

    def string(self, node, key, choices=None, allow_empty=True):
        if not isinstance(node, yaml.ScalarNode) or node.tag != "tag:yaml.org,2002:str":
            self.fail(node, key, f"must be a string, not {self.show(node)}")
        v = node.value
        if choices is not None and v not in choices:
            self.fail(node, key, f"must be one of {', '.join(choices)}, not '{v}'")
        if not allow_empty and not v:
            self.fail(node, key, "must not be empty")
        return v

    def switch(self, node, key):
        # YAML 1.1 reads a bare on/off as a boolean: both spellings are accepted.
        v = self.value(node) if isinstance(node, yaml.ScalarNode) else None
        if v is True or v == "on":
            return "on"
        if v is False or v == "off":
            return "off"
        self.fail(node, key, f"must be on or off, not {self.show(node)}")

    @staticmethod
    def show(node):
        if isinstance(node, yaml.ScalarNode):
            return f"'{node.value}'"
        return "a list" if isinstance(node, yaml.SequenceNode) else "a mapping"


TOP_KEYS = ("scenario", "runs", "seed", "shards", "out", "run", "slurm", "dask")


def not_utf8(path, raw, offset):
    """FILE:LINE: key 'k': the message for a byte at `offset` that is not UTF-8; the key is
    the top-level key whose region holds the line (its last `name:` line at column 0 up to it),
    `(top level)` when there is none."""
    line = raw.count(b"\n", 0, offset) + 1
    column = offset - (raw.rfind(b"\n", 0, offset) + 1) + 1
    key = "(top level)"
    for text in raw[:raw.find(b"\n", offset) if b"\n" in raw[offset:] else len(raw)].split(b"\n"):
        m = re.match(rb"([A-Za-z_][A-Za-z0-9_]*)\s*:", text)
        if m:
            key = m.group(1).decode("ascii")
    return (f"{path}:{line}: key '{key}': not valid UTF-8 (byte 0x{raw[offset]:02x} at column "
            f"{column})")


def load_campaign(path):
    """Returns the checked campaign as a dict with absolute paths and every default filled."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise CampaignError(f"{path}: cannot read: {e.strerror}")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise CampaignError(not_utf8(path, raw, e.start)) from None
    p = Parser(path)
    try:
        root = yaml.compose(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = mark.line + 1 if mark else 1
        raise CampaignError(f"{path}:{line}: not valid YAML: {getattr(e, 'problem', e)}")
    if root is None:
        raise CampaignError(f"{path}:1: key 'scenario': required (the file is empty)")
    top = p.mapping(root, "", TOP_KEYS)
    for req in ("scenario", "runs"):
        if req not in top:
            p.fail(root, req, "required")
    base = os.path.dirname(os.path.abspath(path))
    c = {"campaign_file": os.path.abspath(path)}

    knode, vnode = top["scenario"]
    scen = p.string(vnode, "scenario", allow_empty=False)
    c["scenario"] = os.path.normpath(os.path.join(base, scen))
    if not os.path.isfile(c["scenario"]):
        p.fail(vnode, "scenario", f"no such file: {c['scenario']}")

    c["runs"] = p.integer(top["runs"][1], "runs", 1, 10000)
    c["seed"] = p.integer(top["seed"][1], "seed", 0, MAX_SEED) if "seed" in top else None
    if "shards" in top:
        vnode = top["shards"][1]
        c["shards"] = p.integer(vnode, "shards", 1)
        if c["shards"] > c["runs"]:
            p.fail(vnode, "shards", f"must be at most runs ({c['runs']}), not {c['shards']}")
    else:
        c["shards"] = min(c["runs"], 8)
    stem = os.path.splitext(os.path.basename(path))[0]
    out = p.string(top["out"][1], "out", allow_empty=False) if "out" in top else \
        os.path.join("campaigns", stem)
    c["out"] = os.path.normpath(os.path.join(base, out))
    # Where `out` came from, for errors about the folder: the campaign file's line, or -o.
    c["out_origin"] = (f"{path}:{top['out'][1].start_mark.line + 1}: key 'out'" if "out" in top
                       else f"{path}: key 'out' (default)")

    run = {}
    if "run" in top:
        for name, (k, v) in p.mapping(top["run"][1], "run", RUN_KEYS).items():
            key = f"run.{name}"
            if name in ("reality", "timing"):
                run[name] = p.switch(v, key)
            elif name == "compensation":
                run[name] = p.string(v, key, COMPENSATIONS)
            elif name == "duration":
                d = p.value(v) if isinstance(v, yaml.ScalarNode) else None
                if isinstance(d, bool) or not isinstance(d, (int, float)) or \
                        not math.isfinite(d) or d <= 0:
                    p.fail(v, key, f"must be a number of seconds > 0, not {p.show(v)}")
                run[name] = float(d)
    c["run"] = run

    slurm = {"partition": "", "time_limit": "01:00:00", "cpus_per_task": 1, "sbatch_args": []}
    if "slurm" in top:
        for name, (k, v) in p.mapping(top["slurm"][1], "slurm",
                                      ("partition", "time_limit", "cpus_per_task",
                                       "sbatch_args")).items():
            key = f"slurm.{name}"
            if name == "partition":
                slurm[name] = p.string(v, key, allow_empty=False)
            elif name == "time_limit":
                raw = v.value if isinstance(v, yaml.ScalarNode) else None
                m = re.fullmatch(r"(?:(\d+)-)?(\d{1,3}):(\d{2}):(\d{2})", raw or "")
                if not m or int(m.group(3)) >= 60 or int(m.group(4)) >= 60 or \
                        all(int(g or 0) == 0 for g in m.groups()):
                    p.fail(v, key, f"must be a time limit \"HH:MM:SS\" (or \"D-HH:MM:SS\"), "
                                   f"not {p.show(v)}")
                slurm[name] = raw
            elif name == "cpus_per_task":
                slurm[name] = p.integer(v, key, 1, 4096)
            else:
                if not isinstance(v, yaml.SequenceNode):
                    p.fail(v, key, f"must be a list of strings, not {p.show(v)}")
                slurm[name] = [p.string(item, key) for item in v.value]
    c["slurm"] = slurm

    dask = {"scheduler": "", "workers": os.cpu_count() or 1}
    if "dask" in top:
        for name, (k, v) in p.mapping(top["dask"][1], "dask", ("scheduler", "workers")).items():
            key = f"dask.{name}"
            if name == "scheduler":
                s = p.string(v, key)
                if s and not re.fullmatch(r"(tcp|tls)://[^\s:/]+:\d+", s):
                    p.fail(v, key, f"must be \"\" (a local cluster) or tcp://host:port, not '{s}'")
                dask[name] = s
            else:
                dask[name] = p.integer(v, key, 1, 4096)
    c["dask"] = dask
    return c


def scenario_seed(path):
    """The scenario's own first seed (its top-level `seed`, default 1; docs/scenarios.md)."""
    try:
        with open(path, encoding="utf-8") as f:
            doc = yaml.safe_load(f)
        s = doc.get("seed", 1) if isinstance(doc, dict) else 1
        return s if isinstance(s, int) else 1
    except (OSError, yaml.YAMLError):
        return 1


# --------------------------------------------------------------------------------------------
# Shards

def read_json(path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


class Shard:
    def __init__(self, campaign, index, fnmpc):
        self.c = campaign
        self.index = index
        self.n = campaign["shards"]
        self.label = f"{index}/{self.n}"
        self.dir = os.path.join(campaign["out"], "shards", f"shard-{index}")
        self.log = os.path.join(campaign["out"], "logs", f"shard-{index}.log")
        self.runs = list(range(index, campaign["runs"], self.n))  # 0-based run indices
        self.fnmpc = fnmpc
        self.state = "pending"
        self.exit_code = None
        self.duration = None
        self.slurm_state = None
        self.done_before = self.runs_done()

    def command(self, threads=None):
        c = self.c
        cmd = [self.fnmpc, "run", c["scenario"], "--runs", str(c["runs"]),
               "--shard", self.label, "--resume", "-o", self.dir, "-q"]
        if c["seed"] is not None:
            cmd += ["--seed", str(c["seed"])]
        for key in RUN_KEYS:
            if key in c["run"]:
                v = c["run"][key]
                cmd += [f"--{key}", repr(v) if isinstance(v, float) else str(v)]
        if threads:
            cmd += ["--threads", str(threads)]
        return cmd

    def summary(self):
        return read_json(os.path.join(self.dir, "summary.json"))

    def complete_runs(self):
        """The 0-based indices of this shard's runs whose own summary says complete."""
        done = set()
        for r in self.runs:
            s = read_json(os.path.join(self.dir, f"run-{r + 1:02d}", "summary.json"))
            if s and s.get("complete") is True:
                done.add(r)
        return done

    def runs_done(self):
        return len(self.complete_runs())

    def is_complete(self):
        """Complete and mergeable: the shard summary of this experiment says complete."""
        s = self.summary()
        return bool(s) and s.get("complete") is True and s.get("shard") == self.label and \
            s.get("runs_requested") == self.c["runs"]

    def first_seed(self):
        s = self.summary()
        if s and isinstance(s.get("first_seed"), int):
            return s["first_seed"]
        return self.c["seed"] if self.c["seed"] is not None else scenario_seed(self.c["scenario"])

    def incomplete(self):
        """[(run-NN, seed)] of this shard's runs that did not complete."""
        s0 = self.first_seed()
        by_dir = {}
        s = self.summary()
        for r in (s or {}).get("run_summaries", []) or []:
            if isinstance(r, dict) and "dir" in r:
                by_dir[r["dir"]] = r
        done = self.complete_runs()
        out = []
        for r in self.runs:
            name = f"run-{r + 1:02d}"
            if r in done:
                continue
            seed = by_dir.get(name, {}).get("seed", s0 + r)
            out.append((name, seed))
        return out

    def record(self):
        d = {"index": self.index, "shard": self.label,
             "dir": os.path.relpath(self.dir, self.c["out"]),
             "log": os.path.relpath(self.log, self.c["out"]),
             "runs": [f"run-{r + 1:02d}" for r in self.runs],
             "seeds": [self.first_seed() + r for r in self.runs],
             "state": self.state, "exit_code": self.exit_code,
             "duration_s": None if self.duration is None else round(self.duration, 3),
             "runs_complete_before": self.done_before, "runs_complete": self.runs_done()}
        if self.slurm_state is not None:
            d["slurm_state"] = self.slurm_state
        if self.state not in ("done", "skipped"):
            d["incomplete"] = [{"run": n, "seed": s} for n, s in self.incomplete()]
        return d

    def finish(self, rc, duration):
        """Sets the state from fnmpc's exit code and the folder the shard left."""
        if rc is not None and rc < 0:  # killed by a signal: the shell's convention
            rc = 128 - rc
        self.exit_code = rc
        self.duration = duration
        if rc in (0, 3) and self.is_complete():
            self.state = "done"
        elif rc in (130, 143) and stop.signum:
            self.state = "cancelled"
        else:
            self.state = "failed"

    def failure_message(self):
        if self.exit_code is None:
            how = f"ended without an exit code (Slurm state {self.slurm_state or 'unknown'})"
        else:
            what = FNMPC_EXIT.get(self.exit_code, "")
            how = f"exit {self.exit_code}" + (f" ({what})" if what else "")
            if self.slurm_state and self.slurm_state != "COMPLETED":
                how += f", Slurm state {self.slurm_state}"
        runs = ", ".join(f"{n} (seed {s})" for n, s in self.incomplete()) or \
            "none (but its summary is not complete)"
        return (f"campaign: shard {self.label} failed, {how}; runs not complete: {runs}; "
                f"log: {self.log}")


# --------------------------------------------------------------------------------------------
# Signals, progress

class Stop:
    signum = 0

    def handler(self, signum, frame):
        if not self.signum:
            self.signum = signum
            print(f"campaign: {signal.Signals(signum).name}, cancelling", file=sys.stderr,
                  flush=True)


stop = Stop()


def fmt_time(s):
    s = int(round(s))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}" if s >= 3600 else \
        f"{s // 60:02d}:{s % 60:02d}"


class Progress:
    def __init__(self, shards, quiet):
        self.shards = shards
        self.quiet = quiet
        self.t0 = time.monotonic()
        self.runs_total = sum(len(s.runs) for s in shards)
        self.runs_start = sum(s.done_before for s in shards)
        self.last = None
        self.last_t = -1e9
        self.final = {}
        self.tty = sys.stderr.isatty()

    def update(self, force=False):
        if self.quiet:
            return
        now = time.monotonic()
        if not force and now - self.last_t < 1:
            return
        done_shards = sum(s.state in ("done", "skipped") for s in self.shards)
        runs = sum(self.runs_of(s) for s in self.shards)
        elapsed = now - self.t0
        new = runs - self.runs_start
        if runs >= self.runs_total:
            eta = "00:00"
        elif new > 0:
            eta = fmt_time(elapsed / new * (self.runs_total - runs))
        else:
            eta = "--:--"
        key = (done_shards, runs)
        if key == self.last:
            if force and now - self.last_t < 1:
                return  # said a moment ago
            if not force and not self.tty and now - self.last_t < 60:
                return  # a log: a line when something changed, else one a minute
        self.last, self.last_t = key, now
        line = (f"campaign: shards {done_shards}/{len(self.shards)} done, runs "
                f"{runs}/{self.runs_total}, {fmt_time(elapsed)} elapsed, ETA {eta}")
        if self.tty:
            print("\r" + line + "\033[K", end="", file=sys.stderr, flush=True)
        else:
            print(line, file=sys.stderr, flush=True)

    def runs_of(self, shard):
        """The shard's complete runs; read once more after it ended, then remembered."""
        if shard in self.final:
            return self.final[shard]
        n = shard.runs_done()
        if shard.state in ("done", "skipped", "failed", "cancelled"):
            self.final[shard] = n
        return n

    def end(self):
        if not self.quiet and self.tty:
            print(file=sys.stderr, flush=True)


def set_pdeathsig():
    """In the child: die with the process that started it (a killed driver or Dask worker)."""
    try:
        import ctypes
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


# --------------------------------------------------------------------------------------------
# Executors

def run_local(c, shards, todo, progress):
    cpus = os.cpu_count() or 1
    pool = max(1, min(len(todo), cpus))
    threads = max(1, cpus // pool)
    queue = list(todo)
    running = {}  # Shard -> (Popen, start, log file)
    try:
        while queue or running:
            while queue and len(running) < pool and not stop.signum:
                s = queue.pop(0)
                log = open(s.log, "a", encoding="utf-8")
                cmd = s.command(threads)
                log.write(f"# {datetime.datetime.now().isoformat(timespec='seconds')} "
                          f"{shlex.join(cmd)}\n")
                log.flush()
                proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                        stdin=subprocess.DEVNULL, start_new_session=True,
                                        preexec_fn=set_pdeathsig)
                s.state = "running"
                running[s] = (proc, time.monotonic(), log)
            if stop.signum:
                for s, (proc, _, _) in running.items():
                    if proc.poll() is None:
                        proc.send_signal(stop.signum)
                for s in queue:
                    s.state = "cancelled"
                queue = []
            for s, (proc, t0, log) in list(running.items()):
                rc = proc.poll()
                if rc is not None:
                    log.close()
                    del running[s]
                    s.finish(rc, time.monotonic() - t0)
                    if s.state == "failed":
                        print(s.failure_message(), file=sys.stderr, flush=True)
                    progress.update(force=True)
            progress.update()
            time.sleep(0.2)
    finally:
        for s, (proc, _, log) in running.items():  # only on an exception: leave nothing behind
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            log.close()
    return {}


def slurm_cmd(args, check=True):
    try:
        r = subprocess.run(args, capture_output=True, text=True)
    except FileNotFoundError:
        raise CampaignError(f"{args[0]}: not found (is Slurm installed? scripts/install-deps.sh)")
    if check and r.returncode != 0:
        raise CampaignError(f"{shlex.join(args)}: exit {r.returncode}: {r.stderr.strip()}")
    return r


def write_array_script(c, shards):
    sdir = os.path.join(c["out"], "slurm")
    os.makedirs(sdir, exist_ok=True)
    sl = c["slurm"]
    name = "fnmpc-" + os.path.splitext(os.path.basename(c["campaign_file"]))[0]
    lines = ["#!/bin/bash",
             f"# Written by tools/campaign.py for {c['campaign_file']} (docs/campaigns.md).",
             "# One array task per shard: fnmpc run --shard I/N --resume; its exit code and",
             "# start/end times go to shard-I.rc next to this script.",
             f"#SBATCH --job-name={name}",
             f"#SBATCH --array=0-{len(shards) - 1}",
             f"#SBATCH --output={os.path.join(c['out'], 'logs', 'shard-%a.log')}",
             "#SBATCH --open-mode=append",
             "#SBATCH --ntasks=1",
             f"#SBATCH --cpus-per-task={sl['cpus_per_task']}",
             f"#SBATCH --time={sl['time_limit']}"]
    if sl["partition"]:
        lines.append(f"#SBATCH --partition={sl['partition']}")
    lines += [f"#SBATCH {a}" for a in sl["sbatch_args"]]
    lines += ["set -u", "case $SLURM_ARRAY_TASK_ID in"]
    for s in shards:
        lines.append(f"  {s.index}) cmd=({shlex.join(s.command(sl['cpus_per_task']))}) ;;")
    lines += ['  *) echo "no shard $SLURM_ARRAY_TASK_ID" >&2; exit 1 ;;', "esac",
              f"rc_file={shlex.quote(sdir)}/shard-$SLURM_ARRAY_TASK_ID.rc",
              'rm -f "$rc_file"',
              'start=$(date +%s.%N)',
              'echo "# $(date -Iseconds) slurm job $SLURM_JOB_ID on $(hostname): ${cmd[*]}"',
              # scancel and the time limit signal the batch shell: pass it on to fnmpc, which
              # writes what it flew and marks its summary incomplete.
              '"${cmd[@]}" & pid=$!',
              "trap 'kill -TERM $pid 2>/dev/null' TERM INT",
              'wait $pid; rc=$?',
              'if kill -0 $pid 2>/dev/null; then wait $pid; rc=$?; fi',
              'echo "$rc $start $(date +%s.%N)" > "$rc_file"',
              'exit $rc', ""]
    path = os.path.join(sdir, "array.sh")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines))
    os.chmod(path, 0o755)
    return path


def slurm_active(job):
    """{array task id: state} of the job's tasks still pending or running."""
    r = slurm_cmd(["squeue", "-h", "-r", "-j", str(job), "-o", "%K %T"], check=False)
    if r.returncode != 0:
        if "Invalid job id" in r.stderr:
            return {}
        return None  # slurmctld unreachable for a moment: ask again
    out = {}
    for line in r.stdout.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0].isdigit():
            out[int(parts[0])] = parts[1]
    return out


def slurm_final_states(job):
    """{array task id: (state, exit code)} from sacct, or scontrol without accounting."""
    out = {}
    r = slurm_cmd(["sacct", "-j", str(job), "-X", "-n", "-P", "-o", "JobID,State,ExitCode"],
                  check=False)
    if r.returncode == 0 and r.stdout.strip():
        for line in r.stdout.splitlines():
            parts = line.split("|")
            m = re.fullmatch(rf"{job}_(\d+)", parts[0]) if len(parts) == 3 else None
            if m:
                out[int(m.group(1))] = (parts[1].split()[0], parts[2])
        if out:
            return out
    r = slurm_cmd(["scontrol", "-o", "show", "job", str(job)], check=False)
    for line in r.stdout.splitlines():
        f = dict(kv.split("=", 1) for kv in line.split() if "=" in kv)
        if f.get("ArrayTaskId", "").isdigit():
            out[int(f["ArrayTaskId"])] = (f.get("JobState", "UNKNOWN"), f.get("ExitCode", ""))
    return out


def run_slurm(c, shards, todo, progress, record):
    earlier = (read_json(os.path.join(c["out"], "campaign.json")) or {}).get("slurm", {})
    if earlier.get("job_id") and slurm_active(earlier["job_id"]):
        raise CampaignError(f"Slurm job {earlier['job_id']} of an earlier attempt of this campaign "
                            f"is still pending or running: wait for it or scancel it")
    script = write_array_script(c, shards)
    indices = ",".join(str(s.index) for s in todo)
    for s in todo:
        try:
            os.remove(os.path.join(c["out"], "slurm", f"shard-{s.index}.rc"))
        except FileNotFoundError:
            pass
    r = slurm_cmd(["sbatch", "--parsable", f"--array={indices}", script])
    job = r.stdout.strip().split(";")[0]
    info = {"job_id": job, "script": os.path.relpath(script, c["out"]),
            "array": indices, "submitted": datetime.datetime.now().isoformat(timespec="seconds")}
    record["slurm"] = info
    if not progress.quiet:
        print(f"campaign: submitted Slurm job {job} (array {indices}, {script})",
              file=sys.stderr, flush=True)
    for s in todo:
        s.state = "pending"
    t0 = time.monotonic()
    cancelled = False
    while True:
        if stop.signum and not cancelled:
            slurm_cmd(["scancel", job], check=False)
            cancelled = True
            cancel_t = time.monotonic()
        active = slurm_active(job)
        if active is not None:
            for s in todo:
                if s.index in active:
                    s.state = "running" if active[s.index] == "RUNNING" else "pending"
                    s.slurm_state = active[s.index]
            if not active:
                break
        if cancelled and time.monotonic() - cancel_t > 60:
            print(f"campaign: job {job} still listed 60 s after scancel", file=sys.stderr)
            break
        for s in todo:
            if s.state in ("running", "pending") and active is not None and \
                    s.index not in active and s.exit_code is None:
                collect_slurm_task(c, s, job)
                progress.update(force=True)
        progress.update()
        time.sleep(0.5)
    for s in todo:
        if s.state in ("running", "pending"):
            collect_slurm_task(c, s, job)
    finals = slurm_final_states(job)
    for s in todo:
        if s.index in finals:
            s.slurm_state, code = finals[s.index]
        if s.state == "failed" and not stop.signum:
            print(s.failure_message(), file=sys.stderr, flush=True)
    info["duration_s"] = round(time.monotonic() - t0, 3)
    return info


def collect_slurm_task(c, s, job):
    rc_file = os.path.join(c["out"], "slurm", f"shard-{s.index}.rc")
    rc, duration = None, None
    try:
        with open(rc_file, encoding="utf-8") as f:
            parts = f.read().split()
        rc, duration = int(parts[0]), float(parts[2]) - float(parts[1])
    except (OSError, ValueError, IndexError):
        pass
    if rc is None:
        finals = slurm_final_states(job)
        s.slurm_state = finals.get(s.index, (s.slurm_state, ""))[0]
        s.exit_code, s.duration = None, None
        s.state = "cancelled" if stop.signum else "failed"
        return
    s.finish(rc, duration)
    if stop.signum and s.state != "done":
        s.state = "cancelled"


def dask_shard(cmd, log, event_name):
    """Runs on a Dask worker: one shard's fnmpc run; stops it when the campaign is cancelled."""
    import subprocess as sp
    import time as tm
    try:
        from distributed import Event
        event = Event(event_name)
    except Exception:  # noqa: BLE001 - no client in this worker: no remote cancel
        event = None
    t0 = tm.time()
    with open(log, "a", encoding="utf-8") as f:
        import shlex as sh
        import socket
        f.write(f"# dask worker on {socket.gethostname()}: {sh.join(cmd)}\n")
        f.flush()
        proc = sp.Popen(cmd, stdout=f, stderr=sp.STDOUT, stdin=sp.DEVNULL,
                        preexec_fn=set_pdeathsig)
        last = 0.0
        while proc.poll() is None:
            try:
                proc.wait(timeout=0.5)
            except sp.TimeoutExpired:
                pass
            if event is not None and tm.time() - last > 1.0:
                last = tm.time()
                try:
                    if event.is_set():
                        proc.terminate()
                        proc.wait()
                except Exception:  # noqa: BLE001 - scheduler gone: keep running
                    pass
    return proc.returncode, tm.time() - t0


def run_dask(c, shards, todo, progress, record):
    import logging
    import uuid
    try:
        from distributed import Client, Event, LocalCluster
    except ImportError:
        raise CampaignError("dask.distributed is not installed (python3-distributed, "
                            "scripts/install-deps.sh)")
    for name in ("distributed", "tornado", "asyncio"):
        logging.getLogger(name).setLevel(logging.ERROR)
    d = c["dask"]
    info = {"scheduler": d["scheduler"] or "LocalCluster"}
    record["dask"] = info
    cluster = None
    threads = None
    if d["scheduler"]:
        client = Client(d["scheduler"], timeout=30)
    else:
        cpus = os.cpu_count() or 1
        workers = d["workers"]
        threads = max(1, cpus // min(workers, len(todo)))
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
        info["workers"] = workers
    info["address"] = client.scheduler.address
    event_name = f"fnmpc-campaign-cancel-{uuid.uuid4().hex}"
    event = Event(event_name, client=client)
    t0 = time.monotonic()
    try:
        futures = {}
        for s in todo:
            futures[s] = client.submit(dask_shard, s.command(threads), s.log, event_name,
                                       key=f"fnmpc-shard-{s.index}-{uuid.uuid4().hex[:8]}",
                                       pure=False)
            s.state = "submitted"
        cancelled = False
        while futures:
            if stop.signum and not cancelled:
                event.set()  # the running tasks stop their fnmpc
                pending = [f for f in futures.values() if f.status == "pending"]
                client.cancel(pending)
                cancelled = True
                cancel_t = time.monotonic()
            for s, fut in list(futures.items()):
                if fut.status == "pending" and not cancelled:
                    continue
                if fut.status == "finished":
                    rc, duration = fut.result()
                    s.finish(rc, duration)
                    if stop.signum and s.state != "done":
                        s.state = "cancelled"
                elif fut.status in ("error", "lost"):
                    s.state = "failed"
                    s.exit_code = None
                    s.slurm_state = None
                    print(f"campaign: shard {s.label}: dask task {fut.status}: "
                          f"{fut.exception() if fut.status == 'error' else ''}",
                          file=sys.stderr, flush=True)
                elif fut.status == "cancelled":
                    s.state = "cancelled"
                else:
                    continue
                del futures[s]
                if s.state == "failed" and s.exit_code is not None:
                    print(s.failure_message(), file=sys.stderr, flush=True)
                progress.update(force=True)
            if cancelled and time.monotonic() - cancel_t > 60:
                break
            progress.update()
            time.sleep(0.2)
    finally:
        info["duration_s"] = round(time.monotonic() - t0, 3)
        try:
            client.close(timeout=10)
        except Exception:  # noqa: BLE001
            pass
        if cluster is not None:
            try:
                cluster.close(timeout=10)
            except Exception:  # noqa: BLE001
                pass
    return info


# --------------------------------------------------------------------------------------------
# The campaign

def experiment_key(c):
    """What makes two invocations the same campaign (a rerun resumes it)."""
    return {"scenario": c["scenario"], "runs": c["runs"], "seed": c["seed"],
            "shards": c["shards"], "run": c["run"]}


def write_record(c, record):
    path = os.path.join(c["out"], "campaign.json")
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(record, f, indent=2)
        f.write("\n")
    os.replace(tmp, path)


def resolve_fnmpc(given):
    exe = given or os.environ.get("FNMPC") or shutil.which("fnmpc")
    if not exe:
        raise CampaignError("no fnmpc executable: pass --fnmpc PATH (fnmpc campaign does)")
    if os.sep in exe:
        exe = os.path.abspath(exe)
    elif shutil.which(exe):
        exe = shutil.which(exe)
    if not os.access(exe, os.X_OK):
        raise CampaignError(f"--fnmpc {exe}: not an executable")
    return exe


def main(argv=None):
    ap = argparse.ArgumentParser(prog="fnmpc campaign", description=__doc__.split("\n\n")[0])
    ap.add_argument("campaign", help="campaign YAML (docs/campaigns.md)")
    ap.add_argument("--executor", choices=("local", "slurm", "dask"), default="local")
    ap.add_argument("-o", "--out", help="campaign folder (default: the file's `out`)")
    ap.add_argument("--fnmpc", help="the fnmpc executable the shards and the merge run")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    args = ap.parse_args(argv)

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, stop.handler)
    try:
        return campaign(args)
    except CampaignError as e:
        print(f"campaign: {e}" if not str(e).startswith(args.campaign) else str(e),
              file=sys.stderr)
        return EXIT_ERROR
    except OSError as e:  # a file or folder of the campaign that cannot be written (full disk)
        where = e.filename if e.filename is not None else "campaign folder"
        print(f"campaign: {where}: {e.strerror or e}", file=sys.stderr)
        return EXIT_ERROR


def check_new_campaign_folder(out):
    """A campaign writes over its own files in OUT (logs, scripts, campaign.json, the merge):
    a folder without campaign.json must be new or empty (or hold only the empty shards/ and
    logs/ of an attempt stopped at once), so that no file of anyone else is overwritten."""
    try:
        entries = os.listdir(out)
    except FileNotFoundError:
        return
    except OSError as e:
        raise CampaignError(f"{out}: {e.strerror}")
    if not os.path.isdir(out):
        raise CampaignError(f"{out}: exists and is not a folder")
    foreign = [e for e in entries
               if not (e in ("shards", "logs") and os.path.isdir(os.path.join(out, e))
                       and not os.listdir(os.path.join(out, e)))]
    if foreign:
        raise CampaignError(f"{out}: not empty and not a campaign folder (no campaign.json; "
                            f"holds {sorted(foreign)[0]!r}): choose another -o")


def campaign(args):
    c = load_campaign(args.campaign)
    if args.out:
        c["out"] = os.path.abspath(args.out)
    fnmpc = resolve_fnmpc(args.fnmpc)
    out = c["out"]
    earlier = read_json(os.path.join(out, "campaign.json"))
    if earlier and earlier.get("experiment") != experiment_key(c):
        old, new = earlier.get("experiment") or {}, experiment_key(c)
        diff = next((k for k in new if old.get(k) != new[k]), "experiment")
        raise CampaignError(f"{out} holds another campaign (key '{diff}': {old.get(diff)!r} "
                            f"there, {new.get(diff)!r} now): choose another -o or remove it")
    if not earlier:
        check_new_campaign_folder(out)
    origin = "-o" if args.out else c["out_origin"]
    for sub in ("shards", "logs"):
        try:
            os.makedirs(os.path.join(out, sub), exist_ok=True)
        except OSError as e:
            raise CampaignError(f"{origin}: cannot make the campaign folder {e.filename}: "
                                f"{e.strerror}") from None
    shards = [Shard(c, i, fnmpc) for i in range(c["shards"])]
    todo = []
    for s in shards:
        if s.is_complete():
            s.state = "skipped"
        else:
            todo.append(s)
    record = {"campaign_file": c["campaign_file"], "executor": args.executor, "fnmpc": fnmpc,
              "experiment": experiment_key(c),
              "attempt": (earlier or {}).get("attempt", 0) + 1,
              "started": datetime.datetime.now().isoformat(timespec="seconds"),
              "state": "running", "shards": [s.record() for s in shards]}
    if earlier and args.executor == "slurm" and "slurm" in earlier:
        record["slurm"] = earlier["slurm"]
    write_record(c, record)
    progress = Progress(shards, args.quiet)
    if not args.quiet and len(todo) < len(shards):
        print(f"campaign: {len(shards) - len(todo)} of {len(shards)} shards complete from an "
              f"earlier attempt, skipped", file=sys.stderr, flush=True)
    progress.update(force=True)
    t0 = time.monotonic()
    try:
        if todo and not stop.signum:
            if args.executor == "local":
                run_local(c, shards, todo, progress)
            elif args.executor == "slurm":
                run_slurm(c, shards, todo, progress, record)
            else:
                run_dask(c, shards, todo, progress, record)
    finally:
        record["shards"] = [s.record() for s in shards]
        record["duration_s"] = round(time.monotonic() - t0, 3)
        if todo:
            progress.update(force=True)
        progress.end()
        if sys.exc_info()[0] is not None:
            record["state"] = "error"
            write_record(c, record)

    if stop.signum:
        record["state"] = "cancelled"
        record["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
        write_record(c, record)
        print(f"campaign: cancelled; rerun the same command to resume ({out})", file=sys.stderr)
        return 128 + stop.signum
    failed = [s for s in shards if s.state not in ("done", "skipped")]
    if failed:
        record["state"] = "failed"
        record["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
        write_record(c, record)
        if len(shards) > 1:
            for s in failed:  # once more, together, at the end
                print(s.failure_message(), file=sys.stderr)
        print(f"campaign: {len(failed)} of {len(shards)} shards failed; nothing merged; "
              f"rerun the same command to resume ({out})", file=sys.stderr)
        return EXIT_ERROR

    merged = os.path.join(out, "merged")
    cmd = [fnmpc, "merge"] + [s.dir for s in shards] + ["-o", merged, "--overwrite"]
    tm = time.monotonic()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       stdin=subprocess.DEVNULL)
    sys.stderr.write(r.stderr)
    record["merge"] = {"dir": "merged", "exit_code": r.returncode,
                       "duration_s": round(time.monotonic() - tm, 3)}
    record["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
    if r.returncode not in (0, 3):
        record["state"] = "merge failed"
        write_record(c, record)
        print(f"campaign: {shlex.join(cmd)}: exit {r.returncode}", file=sys.stderr)
        return EXIT_ERROR
    record["state"] = "merged"
    write_record(c, record)
    print(merged, flush=True)
    return r.returncode


if __name__ == "__main__":
    sys.exit(main())
