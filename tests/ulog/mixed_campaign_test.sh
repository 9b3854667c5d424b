#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# A campaign that mixes bench files with a PX4 log (docs/sysid.md, "Campaigns from PX4 logs"):
# the propeller bench and pendulum runs of ../shared/sysid-dev/set3 and the attitude steps and
# flight `fnmpc import-ulog` writes from the SITL log of ../shared/px4-logs. `fnmpc sysid`
# must read both kinds, run every stage (propulsion and inertia from the bench files, the
# attitude model and PD gains from the log) and write the vehicle file; the sanity verdict of
# the log's stages is the log's business (its yaw is not excited: exit 3 is expected there).
# Usage: mixed_campaign_test.sh FNMPC SHARED_DIR
set -euo pipefail
fnmpc=$1
shared=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
set3=$shared/sysid-dev/set3
"$fnmpc" import-ulog "$shared"/px4-logs/sitl/*.ulg -o "$work/imp" --mass 1.0 > /dev/null 2>&1 ||
  fail "import-ulog"
cat > "$work/campaign.yaml" <<YAML
name: mixed-bench-and-log
mass: 1.3172
arm_length: 0.225
propeller_bench: $set3/bench.csv
pendulum:
  wire_separation: 0.3
  wire_length: 1.0
  runs: {x: $set3/pendulum_x.csv, y: $set3/pendulum_y.csv, z: $set3/pendulum_z.csv}
attitude_steps: imp/attitude_steps.csv
flight: imp/flight.csv
YAML
rc=0
"$fnmpc" sysid "$work/campaign.yaml" -o "$work/v.yaml" --no-plots > "$work/out" 2> "$work/err" || rc=$?
[ "$rc" -eq 0 ] || [ "$rc" -eq 3 ] || { cat "$work/err" >&2; fail "sysid exited with $rc"; }
[ -s "$work/v.yaml" ] || fail "no vehicle file written"
/usr/bin/python3 - "$work/v.yaml.report/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
stages = {st["name"]: st for st in s["stages"]}
for name in ("propulsion", "inertia", "attitude model", "PD gains"):
    assert name in stages and stages[name]["ok"], (name, stages.get(name))
# The bench stages come from the bench files and pass their checks
assert all(c["pass"] for c in stages["propulsion"]["checks"]), stages["propulsion"]
assert all(c["pass"] for c in stages["inertia"]["checks"]), stages["inertia"]
# The attitude model comes from the log: roll and pitch fit its held-out segments
for axis in ("roll", "pitch"):
    fit = s["attitude"][axis]["validation"]["chosen_fit_percent"]
    assert fit >= 85.0, (axis, fit)
print("mixed campaign: propulsion and inertia from the bench files, attitude from the PX4 log "
      f"(held-out fit roll {s['attitude']['roll']['validation']['chosen_fit_percent']:.1f} %, "
      f"pitch {s['attitude']['pitch']['validation']['chosen_fit_percent']:.1f} %)")
PY
