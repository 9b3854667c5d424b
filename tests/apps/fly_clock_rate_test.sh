#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Autopilot clocks that do not run at the wall clock's rate (a lockstep PX4 runs about 2 %
# slow; crystals drift): `fnmpc sim-link --clock-rate R` in real time stamps every message on a
# clock R times the simulation's, three `fnmpc fly --clock local` map it onto their own clock
# (autopilot::ClockMap, offset and rate). At R = 0.95 and 1.05 every vehicle must fly the whole
# mission, land and end disarmed (exit 0), with no unusable estimate in flight and the fitted
# rate within 1 % of 1/R. The scenario: ros/fnmpc_ros/test/triangle_20s.yaml with take-off,
# legs and landing 4 s later (the link's handshake allowance), 32 s.
# Usage: fly_clock_rate_test.sh FNMPC SOURCE_DIR AUTOPILOT
set -euo pipefail
fnmpc=$1
src=$2
autopilot=$3
source "$(dirname "$0")/link_test_common.sh"
base=$((42000 + ($$ % 2000) * 10))
vehicles="leader follower1 follower2"

write_short_scenario "$src" triangle "$work/scenario.yaml"

for rate in 0.95 1.05; do
  run=$work/rate-$rate
  "$fnmpc" sim-link "$work/scenario.yaml" --autopilot "$autopilot" --port "$base" \
    --clock-rate "$rate" -o "$run/link" --quiet > /dev/null 2> "$run-sim-link.err" &
  sim=$!
  pids+=("$sim")
  i=0
  fly_pids=()
  for v in $vehicles; do
    "$fnmpc" fly "$v" "$work/scenario.yaml" --link "udpout:127.0.0.1:$((base + i))" \
      --autopilot "$autopilot" -o "$run/fly/$v" --quiet 2> "$run-fly-$v.err" &
    fly_pids+=("$!")
    pids+=("$!")
    i=$((i + 1))
  done
  rc=0
  wait "$sim" || rc=$?
  [ "$rc" -eq 0 ] || { cat "$run-sim-link.err" >&2; fail "rate $rate: sim-link exited with $rc"; }
  i=0
  for p in "${fly_pids[@]}"; do
    frc=0
    wait "$p" || frc=$?
    v=$(echo $vehicles | cut -d' ' -f$((i + 1)))
    if [ "$frc" -ne 0 ]; then
      cat "$run-fly-$v.err" >&2
      /usr/bin/python3 -c "
import json, sys
f = json.load(open(sys.argv[1]))
print('fly-summary:', {k: f.get(k) for k in ('stop', 'session_reason', 'final_phase', 'failsafe',
      'unusable_estimate_steps', 'clock_rate', 'measurement_rates_hz')}, f.get('events'))" \
        "$run/fly/$v/fly-summary.json" >&2 || true
      fail "rate $rate: fly $v exited with $frc"
    fi
    i=$((i + 1))
  done
  /usr/bin/python3 - "$run" "$rate" $vehicles <<'PY'
import json, sys
run, rate, vehicles = sys.argv[1], float(sys.argv[2]), sys.argv[3:]
link = json.load(open(f"{run}/link/summary.json"))
assert link["every_vehicle_armed_flew_and_landed"], link["vehicles"]
for v in vehicles:
    fly = json.load(open(f"{run}/fly/{v}/fly-summary.json"))
    assert fly["stop"] == "disarmed", (v, fly["stop"], fly["session_reason"])
    assert fly["unusable_estimate_steps"] == 0, (v, fly["unusable_estimate_steps"])
    assert abs(fly["clock_rate"] * rate - 1.0) < 0.01, (v, fly["clock_rate"], rate)
    assert not link["vehicles"][v]["armed_at_end"], v
print(f"autopilot clock at {rate}: every vehicle flew, landed and disarmed, 0 unusable "
      f"estimates, fitted rate {json.load(open(f'{run}/fly/leader/fly-summary.json'))['clock_rate']:.4f} "
      f"(1/R {1 / rate:.4f}), mean formation error {link['mean_formation_error_m']:.4f} m")
PY
  base=$((base + 5))
done
