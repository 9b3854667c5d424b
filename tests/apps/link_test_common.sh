# SPDX-License-Identifier: BSD-3-Clause
# Sourced by the real-time link tests (fly_bridge_test.sh, fly_clock_rate_test.sh,
# fly_listen_junk_test.sh, fly_link_loss_test.sh): a work folder removed at exit with every process in `pids`
# killed, `fail`, and the short scenarios they fly.
work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# write_short_scenario SOURCE_DIR triangle|single OUT: ros/fnmpc_ros/test/triangle_20s.yaml
# with take-off, legs and landing 4 s later (the link's handshake allowance), 32 s (the
# landing ends about 27 s: 5 s for the land detector and the disarm); or
# config/scenarios/single.yaml cut to two legs, 25 s.
write_short_scenario() {
  /usr/bin/python3 - "$1" "$2" "$3" <<'PY'
import os, sys, yaml
src_dir, kind, dst = sys.argv[1:]
src = os.path.join(src_dir, "ros/fnmpc_ros/test/triangle_20s.yaml" if kind == "triangle"
                   else "config/scenarios/single.yaml")
s = yaml.safe_load(open(src))
for key in ("vehicle_file", "sensors_file"):
    s[key] = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(src)), s[key]))
if kind == "triangle":
    s["phases"]["takeoff_time"] += 4.0
    s["leader"]["start_time"] += 4.0
    s["phases"]["landing_time"] += 4.0
    s["duration"] = 32.0
else:
    s["phases"]["takeoff_time"] = 5.0
    s["leader"]["start_time"] = 9.0
    s["leader"]["waypoints"] = [[1.0, 0.0, 0.5], [0.0, 0.0, 0.0]]
    s["leader"]["leg_duration"] = 2.0
    s["leader"]["hold_duration"] = 1.0
    s["phases"]["landing_time"] = 15.0
    s["duration"] = 25.0
yaml.safe_dump(s, open(dst, "w"), sort_keys=False)
PY
}
