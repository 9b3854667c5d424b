# SPDX-License-Identifier: BSD-3-Clause
"""studies/onboard/onboard-count.py without qemu: the qemu-log parser that counts the
instructions of a control step, and the active-set line fitted from a counts CSV
(docs/onboard.md)."""
import importlib.util
import os
import subprocess
import sys

import pytest

SCRIPT = os.path.join(os.environ.get("FNMPC_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..")),
                      "studies", "onboard", "onboard-count.py")
spec = importlib.util.spec_from_file_location("onboard_count", SCRIPT)
onboard_count = importlib.util.module_from_spec(spec)
spec.loader.exec_module(onboard_count)


def translation(ptr, size, symbol=""):
    """One block translated by qemu (in_asm) and its first execution (exec)."""
    lines = [b"----------------\n", b"IN: " + symbol.encode() + b"\n"]
    lines += [b"0x%016x:  d503201f  nop\n" % (0x400000 + 4 * i) for i in range(size)]
    lines += [b"\n", execution(ptr, symbol)]
    return lines


def execution(ptr, symbol=""):
    return b"Trace 0: " + ptr.encode() + b" [0000000000000000/0000000000400000/00000000/00000000] " + \
        symbol.encode() + b"\n"


def synthetic_log():
    # Outside a step: block A (3 instructions). Step 1: begin (1), A twice, B (2), end.
    # Step 2: begin, B, end. Then A again, outside any step.
    log = translation("0x7f0000000100", 3)
    log += translation("0x7f0000000200", 1, "fnmpc_bench_step_begin")
    log += [execution("0x7f0000000100"), execution("0x7f0000000100")]
    log += translation("0x7f0000000300", 2)
    log += translation("0x7f0000000400", 1, "fnmpc_bench_step_end")
    log += [execution("0x7f0000000200", "fnmpc_bench_step_begin"), execution("0x7f0000000300"),
            execution("0x7f0000000400", "fnmpc_bench_step_end"), execution("0x7f0000000100")]
    return log


def test_a_step_counts_the_instructions_of_every_block_executed_inside_it():
    assert onboard_count.count_log(iter(synthetic_log()), singlestep=False) == [1 + 3 + 3 + 2, 1 + 2]


def test_singlestep_counts_executed_blocks():
    assert onboard_count.count_log(iter(synthetic_log()), singlestep=True) == [4, 2]


def test_an_end_without_a_begin_is_no_step():
    log = translation("0x7f0000000400", 1, "fnmpc_bench_step_end") + translation("0x7f0000000100", 3)
    assert onboard_count.count_log(iter(log), singlestep=False) == []


def write_counts(path, rows):
    with open(path, "w") as f:
        f.write("problem,scenario,step,instructions\n")
        for r in rows:
            f.write(",".join(str(v) for v in r) + "\n")


def test_the_active_set_line_is_recovered_from_counts_and_reference(tmp_path):
    counts, reference = tmp_path / "counts.csv", tmp_path / "reference.csv"
    changes = {0: 7, 4: 0, 8: 3, 12: 10, 16: 1}
    # Instructions exactly 1000 + 250 per change on the sampled steps; step 0 (left out) and
    # unsampled steps far off the line, so the fit must use exactly the joined steps.
    write_counts(counts, [("F2-reduced", "aggressive", k, 1000 + 250 * c if k else 10**9)
                          for k, c in changes.items()] +
                 [("F2-reduced", "aggressive", 5, 10**9)])
    with open(reference, "w") as f:
        f.write("problem,scenario,step,error_m,kkt,qp_iterations\n")
        for k, c in changes.items():
            f.write(f"F2-reduced,aggressive,{k},0.1,0.01,{c}\n")
    out = subprocess.run([sys.executable, SCRIPT, "--from-csv", str(counts), "--fit-active-set",
                          str(reference)], capture_output=True, text=True, check=True).stdout
    assert "fit F2-reduced aggressive: 4 sampled steps, 0..10 active-set changes: 1000 + 250 per change" in out
    assert "largest sampled count 3500 at 10 changes" in out


def test_counts_without_any_change_get_no_line(tmp_path):
    counts, reference = tmp_path / "counts.csv", tmp_path / "reference.csv"
    write_counts(counts, [("L", "nominal", k, 148164) for k in range(1, 4)])
    with open(reference, "w") as f:
        f.write("problem,scenario,step,error_m,kkt,qp_iterations\n")
        for k in range(1, 4):
            f.write(f"L,nominal,{k},0.1,0.01,0\n")
    out = subprocess.run([sys.executable, SCRIPT, "--from-csv", str(counts), "--fit-active-set",
                          str(reference)], capture_output=True, text=True, check=True).stdout
    assert "fit L nominal: 3 sampled steps, all with 0 active-set changes: no line" in out


@pytest.mark.parametrize("args, message", [
    ([], "give either the aarch64 fnmpc executable or --from-csv FILE"),
    (["fnmpc", "--from-csv", "x.csv"], "give either the aarch64 fnmpc executable or --from-csv FILE"),
])
def test_bad_arguments_are_refused(args, message):
    proc = subprocess.run([sys.executable, SCRIPT] + args, capture_output=True, text=True)
    assert proc.returncode == 2
    assert message in proc.stderr


def test_a_counts_file_without_the_problem_asked_for_is_refused(tmp_path):
    counts = tmp_path / "counts.csv"
    write_counts(counts, [("L", "nominal", 1, 148164)])
    proc = subprocess.run([sys.executable, SCRIPT, "--from-csv", str(counts), "--problem", "F6"],
                          capture_output=True, text=True)
    assert proc.returncode != 0
    assert "no counts of the problems and scenarios asked for" in proc.stderr


def test_a_counts_file_is_summarised_like_a_qemu_run(tmp_path):
    counts = tmp_path / "counts.csv"
    # Step 0 is left out of the summary; the steps are read by number, not by line order.
    write_counts(counts, [("F6", "nominal", 2, 300), ("F6", "nominal", 0, 9000),
                          ("F6", "nominal", 1, 100), ("F6", "nominal", 3, 200)])
    out = subprocess.run([sys.executable, SCRIPT, "--from-csv", str(counts)],
                         capture_output=True, text=True, check=True).stdout
    assert out.splitlines()[1].split() == ["F6", "nominal", "3", "200", "300", "300", "9000"]
