#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The triangle flown through the ROS 2 nodes (ros2/launch/formation.sh, lockstep, Cyclone on
# loopback). Modes:
#   vs-cli  the true trajectories equal `fnmpc run`'s on the same scenario and seed (every
#           vehicle, every control instant, to the CSVs' 1e-5 m) and the followers' mean
#           formation error over the formation window is within 5 % (the ROS 1 tolerance);
#   record  the recorder's run folder (ros2/launch/formation.sh --record) goes through
#           `fnmpc report` (exit 0, report.html) and its summary's mean and steady-state formation
#           errors are within 5 % of `fnmpc run`'s;
#   fastdds the leader is flown by a Fast DDS program using only the ROS 2 conventions
#           (fastdds_formation_peer, FASTDDS_PEER): it answers the leader's syncs with setpoints
#           holding 1.5 m, receives every topic of the run and checks their types and type hashes;
#   kill    follower2's node is killed (SIGKILL) once the flight passed t = 8 s: the simulator
#           declares it dead, its autopilot's failsafe puts it on the ground, the leader and
#           follower1 fly on to the end, the simulator finishes (exit 0).
# Usage: formation_test.sh MODE BUILD_DIR FNMPC_CLI SCENARIO WORK_DIR
set -euo pipefail
mode=$1 build=$2 cli=$3 scenario=$4 work=$5
here=$(cd "$(dirname "$0")/.." && pwd)
rm -rf "$work" && mkdir -p "$work"
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-63}
py=/usr/bin/python3
case $mode in
  vs-cli)
    "$here/launch/formation.sh" "$build" "$scenario" "$work/ros2"
    "$cli" run "$scenario" -o "$work/cli" -q --threads 1 >/dev/null 2>&1 || true  # its landing check may fail; the CSVs are written
    $py - "$work/ros2/truth.csv" "$work/cli" <<'PY'
import csv, statistics, sys, json
truth, cli = sys.argv[1], sys.argv[2]
ros = {}
for r in csv.DictReader(open(truth)):
    ros[(r['vehicle'], r['t'])] = r
window = json.load(open(cli + '/run-01/summary.json'))['formation_window_s']
names = sorted({k[0] for k in ros})
worst, compared = 0.0, 0
for v in names:
    mine, theirs = [], []
    for r in csv.DictReader(open(f'{cli}/run-01/{v}.csv')):
        k = (v, r['t'])
        if k not in ros:
            continue
        compared += 1
        for axis in 'xyz':
            worst = max(worst, abs(float(r[axis]) - float(ros[k][axis])))
        if window[0] <= float(r['t']) <= window[1] and r['formation_error'] != 'nan':
            theirs.append(float(r['formation_error']))
            mine.append(float(ros[k]['formation_error']))
    if theirs:
        a, b = statistics.mean(mine), statistics.mean(theirs)
        print(f'{v}: mean formation error over {window} s: ROS 2 {a:.5f} m, fnmpc run {b:.5f} m')
        if abs(a - b) > 0.05 * b:
            sys.exit(f'{v}: mean formation error differs by more than 5 %')
print(f'{compared} vehicle-instants compared, largest position difference {worst:.2e} m')
if compared < 3 * 390 or worst > 2e-5:
    sys.exit('the ROS 2 run does not reproduce fnmpc run')
PY
    ;;
  fastdds)
    "$here/launch/formation.sh" "$build" "$scenario" "$work/ros2" --external leader -- \
      -p ground_truth_subscribers:=1 >"$work/launch.log" 2>&1 &
    launch=$!
    peer_rc=0
    "$FASTDDS_PEER" "$ROS_DOMAIN_ID" leader 1.37 1.5 20.0 >"$work/peer.log" 2>&1 || peer_rc=$?
    rc=0; wait "$launch" || rc=$?
    cat "$work/launch.log" "$work/peer.log"
    [[ $rc == 0 && $peer_rc == 0 ]] || { echo "simulator exit $rc, peer exit $peer_rc"; exit 1; }
    grep -q "scenario finished at t = 20.00 s, 0 vehicle(s) declared dead" "$work/ros2/sim.log" ||
      { echo "the simulator declared a vehicle dead"; exit 1; }
    ;;
  record)
    "$here/launch/formation.sh" "$build" "$scenario" "$work/ros2" --record
    "$cli" run "$scenario" -o "$work/cli" -q --threads 1 >/dev/null 2>&1 || true
    # A build without the replay bundle (FNMPC_WITH_REPLAY=OFF) makes report exit 1 after the
    # plots and report.html: only that failure is accepted.
    report_rc=0
    PATH=/usr/bin:$PATH "$cli" report "$work/ros2/run" >"$work/report.log" 2>&1 || report_rc=$?
    if [[ $report_rc != 0 ]] && ! grep -q "replay.html not written: .*replay.bundle.js missing" "$work/report.log"; then
      cat "$work/report.log"; exit 1
    fi
    for f in report.html formation_errors.png trajectories_3d.png; do
      [[ -s $work/ros2/run/$f ]] || { cat "$work/report.log"; echo "fnmpc report wrote no $f"; exit 1; }
    done
    $py - "$work/ros2/run/summary.json" "$work/cli/run-01/summary.json" <<'PY'
import json, sys
ros, cli = (json.load(open(f)) for f in sys.argv[1:3])
for key in ('mean_formation_error_m', 'steady_state_formation_error_m'):
    a, b = ros[key], cli[key]
    print(f'{key}: recorded ROS 2 run {a:.6f} m, fnmpc run {b:.6f} m')
    assert abs(a - b) <= 0.05 * b, key
for v in ('leader', 'follower1', 'follower2'):
    assert ros['vehicles'][v]['control_steps'] == 401, (v, ros['vehicles'][v]['control_steps'])  # every setpoint
PY
    ;;
  kill)
    "$here/launch/formation.sh" "$build" "$scenario" "$work/ros2" >"$work/launch.log" 2>&1 &
    launch=$!
    pid=""
    for _ in $(seq 600); do  # the node's pid, then the flight past 8 s (at most 60 s each)
      pid=$(sed -n 's|^formation: vehicle node /follower2 (pid \([0-9]*\))$|\1|p' "$work/launch.log")
      [[ -n $pid ]] && break
      sleep 0.1
    done
    [[ -n $pid ]] || { cat "$work/launch.log"; echo "no follower2 node"; exit 1; }
    killed=0
    for _ in $(seq 6000); do
      if grep -q '^8\.000,' "$work/ros2/truth.csv" 2>/dev/null; then
        kill -KILL "$pid"; killed=1; break
      fi
      kill -0 "$launch" 2>/dev/null || break
      sleep 0.01
    done
    rc=0; wait "$launch" || rc=$?
    cat "$work/launch.log"
    [[ $killed == 1 ]] || { echo "the flight ended before t = 8 s was seen"; exit 1; }
    [[ $rc == 0 ]] || { echo "simulator exit $rc"; exit 1; }
    grep -q "vehicle follower2 silent .* declared dead" "$work/ros2/sim.log" || { cat "$work/ros2/sim.log"; exit 1; }
    $py - "$work/ros2/truth.csv" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
last = {r['vehicle']: r for r in rows}
dead = [float(r['t']) for r in rows if r['vehicle'] == 'follower2' and r['live'] == '0']
print(f'follower2 declared dead from t = {dead[0]:.2f} s, final z {float(last["follower2"]["z"]):.3f} m')
assert dead and 8.0 <= dead[0] < 17.0, 'follower2 not declared dead in flight'
assert float(last['follower2']['z']) < 0.15, 'follower2 not on the ground at the end'
for v in ('leader', 'follower1'):
    assert last[v]['live'] == '1', f'{v} declared dead'
    at16 = [r for r in rows if r['vehicle'] == v and r['t'] == '16.000'][0]
    print(f'{v}: alive to the end, z {float(at16["z"]):.3f} m at t = 16 s')
    assert float(at16['z']) > 1.2, f'{v} did not fly on'
PY
    ;;
  *) echo "formation_test: unknown mode $mode" >&2; exit 2 ;;
esac
echo "formation_test $mode: passed"
