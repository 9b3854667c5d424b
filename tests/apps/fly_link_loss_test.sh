#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The autopilot goes silent mid-flight: `fnmpc sim-link` (real time) is killed while three
# `fnmpc fly --clock local` fly the triangle. Every fly must hand back to the autopilot's own
# failsafe because the state stream stopped (docs/autopilot.md, "Failsafe ladder"), send no
# setpoint after that, and exit 3 (session stopped) soon after the kill.
# Usage: fly_link_loss_test.sh FNMPC SOURCE_DIR AUTOPILOT
set -euo pipefail
fnmpc=$1
src=$2
autopilot=$3
scenario=$src/config/scenarios/triangle.yaml
source "$(dirname "$0")/link_test_common.sh"
base=$((40000 + ($$ % 2000) * 10))
vehicles="leader follower1 follower2"

"$fnmpc" sim-link "$scenario" --autopilot "$autopilot" --port "$base" -o "$work/link" --quiet \
  > /dev/null 2> "$work/sim-link.err" &
sim=$!
pids+=("$sim")
i=0
fly_pids=()
for v in $vehicles; do
  "$fnmpc" fly "$v" "$scenario" --link "udpout:127.0.0.1:$((base + i))" --autopilot "$autopilot" \
    -o "$work/fly/$v" 2> "$work/fly-$v.err" &
  fly_pids+=("$!")
  pids+=("$!")
  i=$((i + 1))
done
# Until every vehicle flies its setpoints (at most 60 s), then 3 s more of flight.
for _ in $(seq 600); do
  active=0
  for v in $vehicles; do grep -q "session active" "$work/fly-$v.err" 2>/dev/null && active=$((active + 1)); done
  [ "$active" -eq 3 ] && break
  sleep 0.1
done
[ "$active" -eq 3 ] || { cat "$work"/fly-*.err >&2; fail "not every session became active"; }
sleep 3
kill -9 "$sim"
wait "$sim" 2>/dev/null || true
killed_at=$EPOCHREALTIME
i=0
for v in $vehicles; do
  rc=0
  wait "${fly_pids[$i]}" || rc=$?
  [ "$rc" -eq 3 ] || { cat "$work/fly-$v.err" >&2; fail "fly $v exited with $rc (expected 3)"; }
  i=$((i + 1))
done
took=$(/usr/bin/python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.2f}')" \
  "$killed_at" "$EPOCHREALTIME")
echo "every fly stopped within $took s of the kill"
/usr/bin/python3 -c "import sys; sys.exit(float(sys.argv[1]) >= 10)" "$took" ||
  fail "the flies took $took s to stop"

/usr/bin/python3 - "$work" $vehicles <<'PY'
import csv, json, sys
work, vehicles = sys.argv[1], sys.argv[2:]
for v in vehicles:
    s = json.load(open(f"{work}/fly/{v}/fly-summary.json"))
    assert s["stop"] == "session", (v, s["stop"])
    assert s["session_state"] == "handed_back", (v, s["session_state"])
    assert s["session_reason"] in ("state_stream_lost", "heartbeat_lost"), (v, s["session_reason"])
    handed = [e["t"] for e in s["events"] if e["state"] == "handed_back"]
    assert len(handed) == 1, (v, s["events"])
    rows = list(csv.DictReader(open(f"{work}/fly/{v}/{v}.csv")))
    # The last measurement's arrival: where the cumulative count last grew.
    last_meas = max(float(r["t"]) for a, r in zip(rows, rows[1:])
                    if int(r["measurements"]) > int(a["measurements"]))
    late = [r["t"] for r in rows if float(r["t"]) > handed[0] and r["sent"] == "1"]
    assert not late, (v, "setpoints after the hand-back", late)
    delay = handed[0] - last_meas
    # The state watchdog is 0.2 s: neither before it nor as late as the 1.5 s heartbeat one
    # (rows are control steps, so the last arrival is seen up to one step, 0.05 s, late).
    assert 0.14 <= delay <= 1.0, (v, "hand-back", delay, "s after the last measurement")
    print(f"{v}: handed back ({s['session_reason']}) {delay:.2f} s after the last measurement, "
          f"no setpoint after it")
PY
