#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""Integration test on a held-out identification campaign (docs/sysid.md).

    /usr/bin/python3 heldout_set_test.py FNMPC SYSID_DEV_DIR SET

Runs exactly the documented pipeline on SYSID_DEV_DIR/SET (read in place, never copied):
`fnmpc sysid SET/campaign.yaml -o vehicle.yaml`, `fnmpc calibrate vehicle.yaml SET/flight.csv
-o calibrated.yaml`, then SYSID_DEV_DIR/check_sysid.py SET/truth.yaml calibrated.yaml, and
passes only when sysid exits 0 without a solver log line and the checker reports "16 passed,
0 failed". The folder is expected beside
the repository (../shared/sysid-dev, as in CI); a missing folder is a failure, not a skip.
"""
import os
import re
import subprocess
import sys
import tempfile


def run(cmd, cwd):
    print("$ " + " ".join(cmd), flush=True)
    p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True)
    print(p.stdout)
    return p.returncode, p.stdout


def main(argv):
    if len(argv) != 4:
        print(__doc__)
        return 2
    fnmpc, dev, name = argv[1], os.path.abspath(argv[2]), argv[3]
    s = os.path.join(dev, name)
    for f in ("campaign.yaml", "flight.csv", "truth.yaml"):
        if not os.path.isfile(os.path.join(s, f)):
            print(f"FAIL: {os.path.join(s, f)} not found (the held-out set must be in "
                  f"../shared/sysid-dev beside the repository)")
            return 1
    with tempfile.TemporaryDirectory(prefix="fnmpc_heldout_") as out:
        rc, text = run([fnmpc, "sysid", os.path.join(s, "campaign.yaml"), "-o", "vehicle.yaml"],
                       out)
        # A clean campaign: complete and every sanity check passed (3 would name a failed
        # stage, 2 an incomplete vehicle file), and no solver log lines on stderr.
        if rc != 0:
            print(f"FAIL: fnmpc sysid exited with {rc}, want 0 on this clean campaign")
            return 1
        if re.search(r"^[WE]\d{4} ", text, re.M):
            print("FAIL: a glog (Ceres) line on fnmpc sysid's output")
            return 1
        rc, _ = run([fnmpc, "calibrate", "vehicle.yaml", os.path.join(s, "flight.csv"), "-o",
                     "calibrated.yaml"], out)
        if rc not in (0, 3):
            print(f"FAIL: fnmpc calibrate exited with {rc}")
            return 1
        if not os.path.isfile(os.path.join(out, "vehicle.yaml.report", "summary.md")):
            print("FAIL: the sysid report has no summary.md")
            return 1
        rc, text = run(["/usr/bin/python3", os.path.join(dev, "check_sysid.py"),
                        os.path.join(s, "truth.yaml"), "calibrated.yaml"], out)
    m = re.search(r"^(\d+) passed, (\d+) failed\s*$", text, re.M)
    if not m:
        print("FAIL: no 'N passed, M failed' line in the checker output")
        return 1
    passed, failed = int(m.group(1)), int(m.group(2))
    if passed != 16 or failed != 0 or rc != 0:
        print(f"FAIL: checker: {passed} passed, {failed} failed (exit {rc}); want 16 passed, "
              f"0 failed")
        return 1
    print("OK: 16 passed, 0 failed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
