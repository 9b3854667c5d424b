#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The ROS vehicle node flies through the MAVLink link (~link, docs/autopilot.md): three
# vehicle_nodes against `fnmpc sim-link --lockstep` over UDP on localhost, each session reaching
# active and the formation error within 20 % of `fnmpc run` on the same scenario and seed.
# Usage: link_flight_test.sh FNMPC VEHICLE_NODE SCENARIO
set -euo pipefail
fnmpc=$1
node=$2
scenario=$3
work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
export PATH=/usr/bin:$PATH  # Debian's python3 for the ROS tools
base=$((23000 + ($$ % 2000) * 10))

rosmaster --core -p "${ROS_MASTER_URI##*:}" > "$work/master.log" 2>&1 &
pids+=("$!")
for _ in $(seq 100); do rosnode list > /dev/null 2>&1 && break; sleep 0.1; done
rosnode list > /dev/null 2>&1 || fail "no ROS master at $ROS_MASTER_URI"

# The link's handshake (warm-up, mode and arming confirmed by 1 Hz HEARTBEATs) needs the
# take-off at handshake_time (5 s) or later: the take-off, the leader's legs and the landing
# move 4 s later in both runs. triangle_20s lands from 17 s (21 s here): 28 s leave the landing
# time to finish (the run's outcome and sim-link's "armed, flew and landed" check it),
# everything else as given.
/usr/bin/python3 - "$scenario" "$work/scenario.yaml" <<'PY'
import os, sys, yaml
src, dst = sys.argv[1:]
s = yaml.safe_load(open(src))
for key in ("vehicle_file", "sensors_file"):
    s[key] = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(src)), s[key]))
s["phases"]["takeoff_time"] += 4.0
s["leader"]["start_time"] += 4.0
s["phases"]["landing_time"] += 4.0
s["duration"] = 28.0
yaml.safe_dump(s, open(dst, "w"), sort_keys=False)
PY
scenario=$work/scenario.yaml

"$fnmpc" run "$scenario" -o "$work/inproc" --quiet > /dev/null
"$fnmpc" sim-link "$scenario" --autopilot px4 --lockstep --port "$base" -o "$work/link" \
  --quiet > /dev/null 2> "$work/sim-link.err" &
sim=$!
pids+=("$sim")
i=0
for v in leader follower1 follower2; do
  "$node" __name:=vehicle_node __ns:="/$v" _scenario:="$scenario" _vehicle:="$v" \
    _link:="udpout:127.0.0.1:$((base + i))" _autopilot:=px4 _link_clock:=autopilot \
    > "$work/$v.log" 2>&1 &
  pids+=("$!")
  i=$((i + 1))
done
rc=0
wait "$sim" || rc=$?
[ "$rc" -eq 0 ] || { cat "$work/sim-link.err" "$work"/*.log >&2; fail "sim-link exited with $rc"; }
for v in leader follower1 follower2; do
  grep -q "session active" "$work/$v.log" || { cat "$work/$v.log" >&2; fail "$v never active"; }
done
/usr/bin/python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
a = json.load(open(f"{work}/inproc/summary.json"))["mean_formation_error_m"]
link = json.load(open(f"{work}/link/summary.json"))
assert link["every_vehicle_armed_flew_and_landed"], link["vehicles"]
b = link["mean_formation_error_m"]
rel = abs(b - a) / a
print(f"ROS over MAVLink/UDP: mean formation error {b:.4f} m, in process {a:.4f} m "
      f"({100 * rel:.1f} % apart)")
assert rel <= 0.20, f"{100 * rel:.1f} % apart (limit 20 %)"
PY
