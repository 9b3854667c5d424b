#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Listen mode under junk: `fnmpc fly --link udp:...` listens, `fnmpc sim-link --connect` (real
# time) sends to it, and a third process throws 1000 junk datagrams per second (random bytes,
# some with MAVLink 2 start bytes and headers) at the same port. The replies must stay locked
# on the flight controller (docs/link.md): setpoints reach the autopilot at 19 Hz or more while
# armed, the flight ends disarmed with exit 0 and no unusable estimate. The scenario:
# config/scenarios/single.yaml shortened to 25 s (two legs).
# Usage: fly_listen_junk_test.sh FNMPC SOURCE_DIR AUTOPILOT
set -euo pipefail
fnmpc=$1
src=$2
autopilot=$3
source "$(dirname "$0")/link_test_common.sh"
port=$((44000 + ($$ % 2000) * 10))

write_short_scenario "$src" single "$work/scenario.yaml"

"$fnmpc" fly leader "$work/scenario.yaml" --link "udp:127.0.0.1:$port" --autopilot "$autopilot" \
  -o "$work/fly" --quiet 2> "$work/fly.err" &
fly=$!
pids+=("$fly")
/usr/bin/python3 - "$port" > /dev/null 2>&1 <<'PY' &
import os, random, socket, sys, time
port = int(sys.argv[1])
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
rng = random.Random(1)
start = time.monotonic()
n = 0
while time.monotonic() - start < 40:
    size = rng.randint(1, 300)
    data = bytearray(os.urandom(size))
    if n % 3 == 0 and size >= 10:  # a MAVLink 2 header claiming system 1, component 1
        data[0:10] = bytes([0xFD, rng.randint(0, 255), 0, 0, n & 0xFF, 1, 1,
                            rng.getrandbits(8), rng.getrandbits(8), 0])
    try:
        s.sendto(bytes(data), ("127.0.0.1", port))
    except OSError:
        pass
    n += 1
    time.sleep(max(0.0, start + n / 1000.0 - time.monotonic()))
PY
pids+=("$!")
disown "$!"  # no job-control notice when the cleanup kills it
rc=0
"$fnmpc" sim-link "$work/scenario.yaml" --autopilot "$autopilot" --connect --port "$port" \
  -o "$work/link" --quiet > /dev/null 2> "$work/sim-link.err" || rc=$?
[ "$rc" -eq 0 ] || { cat "$work/sim-link.err" "$work/fly.err" >&2; fail "sim-link exited with $rc"; }
frc=0
wait "$fly" || frc=$?
[ "$frc" -eq 0 ] || { cat "$work/fly.err" >&2; fail "fly exited with $frc"; }
/usr/bin/python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
link = json.load(open(f"{work}/link/summary.json"))
fly = json.load(open(f"{work}/fly/fly-summary.json"))
v = link["vehicles"]["leader"]
assert link["every_vehicle_armed_flew_and_landed"], link["vehicles"]
assert not v["armed_at_end"], v
assert fly["stop"] == "disarmed", (fly["stop"], fly["session_reason"])
assert fly["unusable_estimate_steps"] == 0, fly["unusable_estimate_steps"]
rate = v["setpoint_rate_armed_hz"]
assert rate >= 19.0, v
junk = fly["link_counters"]["bytes_discarded"]
assert junk > 100000, fly["link_counters"]  # the junk did arrive
print(f"listen mode under 1000 junk datagrams/s: setpoints at the autopilot {rate:.2f} Hz while "
      f"armed, {junk} junk bytes discarded, disarmed, exit 0")
PY
