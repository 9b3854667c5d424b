#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The onboard executable flies a scenario through the simulator's MAVLink endpoint over UDP on
# localhost (`fnmpc sim-link --lockstep` + one `fnmpc fly --clock autopilot` per vehicle), and
# its formation error is within 20 % of the same scenario flown in process (`fnmpc run`, same
# seed). Usage: fly_over_udp_test.sh FNMPC SOURCE_DIR AUTOPILOT [SCENARIO]
set -euo pipefail
fnmpc=$1
src=$2
autopilot=$3
scenario=${4:-$src/config/scenarios/triangle.yaml}
# "signed" as the fifth argument: both sides sign with a fresh key (--signing-key).
signed=${5:-}
work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# A port range of our own: ctest may run other tests (and this one for the other autopilot) at
# the same time.
base=$((20000 + ($$ % 2000) * 10))
vehicles=$(/usr/bin/python3 -c "
import sys, yaml
print(' '.join(v['name'] for v in yaml.safe_load(open(sys.argv[1]))['vehicles']))" "$scenario")

sign=()
if [ "$signed" = signed ]; then
  od -An -tx1 -N32 /dev/urandom | tr -d ' \n' > "$work/key.hex"
  sign=(--signing-key "$work/key.hex")
fi

# In process.
"$fnmpc" run "$scenario" -o "$work/inproc" --quiet > /dev/null

# Over the link: the endpoint first, then the onboard computers.
"$fnmpc" sim-link "$scenario" --autopilot "$autopilot" --lockstep --port "$base" "${sign[@]}" \
  -o "$work/link" --quiet > "$work/sim-link.out" 2> "$work/sim-link.err" &
sim=$!
pids+=("$sim")
i=0
fly_pids=()
for v in $vehicles; do
  "$fnmpc" fly "$v" "$scenario" --link "udpout:127.0.0.1:$((base + i))" \
    --autopilot "$autopilot" --clock autopilot -o "$work/fly/$v" --quiet "${sign[@]}" \
    2> "$work/fly-$v.err" &
  fly_pids+=("$!")
  pids+=("$!")
  i=$((i + 1))
done
sim_rc=0
wait "$sim" || sim_rc=$?
fly_rc=()
for p in "${fly_pids[@]}"; do
  rc=0
  wait "$p" || rc=$?
  fly_rc+=("$rc")
done
if [ "$sim_rc" -ne 0 ]; then
  cat "$work/sim-link.err" >&2
  fail "sim-link exited with $sim_rc"
fi
i=0
for v in $vehicles; do
  [ "${fly_rc[$i]}" -eq 0 ] || { cat "$work/fly-$v.err" >&2; fail "fly $v exited with ${fly_rc[$i]}"; }
  i=$((i + 1))
done

/usr/bin/python3 - "$work" "${signed:-unsigned}" $vehicles <<'PY'
import json, sys
work, signed, vehicles = sys.argv[1], sys.argv[2] == "signed", sys.argv[3:]
inproc = json.load(open(f"{work}/inproc/summary.json"))
link = json.load(open(f"{work}/link/summary.json"))
assert link["complete"], link
assert link["every_vehicle_armed_flew_and_landed"], link["vehicles"]
for v in vehicles:
    fly = json.load(open(f"{work}/fly/{v}/fly-summary.json"))
    assert fly["stop"] == "disarmed", (v, fly["stop"], fly["session_reason"])
    assert fly["setpoints_skipped"] == 0, (v, fly["setpoints_skipped"])
    assert fly["link_counters"]["crc_errors"] == 0, fly["link_counters"]
    # The endpoint's other traffic (ids fnmpc does not decode) is skipped, not discarded
    assert fly["link_counters"]["bytes_discarded"] == 0, fly["link_counters"]
    assert fly["link_counters"]["unknown_frames"] > 0, fly["link_counters"]
    assert fly["link_counters"]["signature_failures"] == 0, fly["link_counters"]
    assert fly["link_signed"] == signed, (v, fly["link_signed"])
    # Disarmed by the emulated autopilot's rules (land detector), not left armed
    assert link["vehicles"][v]["armed_at_end"] is False, (v, link["vehicles"][v])
    assert fly["failsafe"] is False and fly["fallbacks"] == 0, fly
    # The IMU stream was asked for at the estimator's rate (MAV_CMD_SET_MESSAGE_INTERVAL)
    # and granted; the estimator never lost its estimate in flight.
    requests = [e for e in fly["events"] if e["reason"] == "stream_request"]
    assert requests and requests[0]["result"] == 0, (v, fly["events"])
    assert fly["unusable_estimate_steps"] == 0, (v, fly["unusable_estimate_steps"])
    imu_rate = fly["measurement_rates_hz"]["imu"]
    assert 0.9 * 250 <= imu_rate <= 1.1 * 250, (v, fly["measurement_rates_hz"])
    states = [e["state"] for e in fly["events"] if e["reason"] != "stream_request"]
    assert states[:4] == ["warming_up", "requesting_mode", "arming", "active"], states
    assert states[-1] == "disarmed", states
a = inproc["mean_formation_error_m"]
b = link["mean_formation_error_m"]
if a is None:  # a single vehicle: no formation error, the flight checks above are the test
    assert b is None, b
    print(f"one vehicle over MAVLink/UDP: flew, landed and disarmed; wall {link['wall_time_s']:.1f} s")
    sys.exit(0)
rel = abs(b - a) / a
print(f"mean formation error: in process {a:.4f} m, over MAVLink/UDP {b:.4f} m "
      f"({100 * rel:.1f} % apart; steady state {inproc['steady_state_formation_error_m']:.4f} "
      f"vs {link['steady_state_formation_error_m']:.4f} m); wall {link['wall_time_s']:.1f} s")
assert rel <= 0.20, f"{100 * rel:.1f} % apart (limit 20 %)"
PY
