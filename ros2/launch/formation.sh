#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Launches a formation on ROS 2 topics (docs/ros2.md): the simulator node and one vehicle node
# per vehicle of SCENARIO (namespace /<vehicle>), on the shipped loopback Cyclone configuration
# unless CYCLONEDDS_URI is set. Ends when the scenario ends (or on Ctrl-C), stopping the
# vehicle nodes with SIGINT; exit status: the simulator's.
#   ros2/launch/formation.sh BUILD_DIR SCENARIO OUT_DIR [--record] [--external VEHICLE]
#                            [-- simulator node arguments, e.g. -p seed:=2]
# --external VEHICLE: no vehicle node for VEHICLE (another program, e.g. a ROS 2 node, flies it).
# OUT_DIR gets truth.csv (simulator) and one log per node; with --record also OUT_DIR/run, the
# run folder of `fnmpc run` written by the recorder (then: fnmpc report OUT_DIR/run).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=$1 scenario=$2 out=$3
shift 3
record=0 external=""
while [[ $# -gt 0 && $1 != -- ]]; do
  case $1 in
    --record) record=1; shift ;;
    --external) external=$2; shift 2 ;;
    *) echo "formation: unknown option $1" >&2; exit 2 ;;
  esac
done
[[ ${1:-} == -- ]] && shift
mkdir -p "$out"
export CYCLONEDDS_URI=${CYCLONEDDS_URI:-file://$here/config/cyclonedds-loopback.xml}
params=$here/config/formation.params.yaml
mapfile -t vehicles < <(/usr/bin/python3 -c 'import sys, yaml
for v in yaml.safe_load(open(sys.argv[1]))["vehicles"]: print(v["name"])' "$scenario")
pids=()
stop() { for p in "${pids[@]}"; do kill -INT "$p" 2>/dev/null || true; done; }
trap 'stop; kill -INT ${sim_pid:-0} 2>/dev/null || true' INT TERM
# A recorder or an external program reads the setpoints too: the vehicle nodes answer the
# first sync only once their setpoint writer has matched it as well as the simulator.
readers=1
[[ $record == 1 || -n $external ]] && readers=2
for v in "${vehicles[@]}"; do
  [[ $v == "$external" ]] && { echo "formation: /$v flown by another program"; continue; }
  "$build/ros2/fnmpc_ros2_vehicle" --ros-args -r __ns:=/"$v" --params-file "$params" \
    -p scenario:="$scenario" -p setpoint_subscribers:="$readers" >"$out/$v.log" 2>&1 &
  pids+=($!)
  echo "formation: vehicle node /$v (pid $!)"
done
sim_args=()
if [[ $record == 1 ]]; then
  "$build/ros2/fnmpc_ros2_record" --ros-args -p scenario:="$scenario" -p out:="$out/run" >"$out/record.log" 2>&1 &
  record_pid=$!
  echo "formation: recorder /record (pid $record_pid)"
  sim_args=(-p ground_truth_subscribers:=1)  # the simulator waits for the recorder
fi
"$build/ros2/fnmpc_ros2_sim" --ros-args -r __node:=sim --params-file "$params" -p scenario:="$scenario" \
  -p truth_csv:="$out/truth.csv" "${sim_args[@]}" "$@" >"$out/sim.log" 2>&1 &
sim_pid=$!
echo "formation: simulator node /sim (pid $sim_pid)"
rc=0
wait "$sim_pid" || rc=$?
stop
for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
if [[ $record == 1 ]]; then
  wait "$record_pid" || { echo "formation: recorder failed: $(tail -1 "$out/record.log")"; rc=1; }
fi
echo "formation: simulator exit $rc; $(tail -1 "$out/sim.log")"
exit "$rc"
