#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The fnmpc command line refuses bad values and reused folders, tells failure by
# its exit code (docs/failure.md), stops cleanly on SIGINT, and `report` answers an
# incomplete folder with one line. Usage: cli_test.sh FNMPC_BINARY SOURCE_DIR
set -uo pipefail
fnmpc=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export PATH=/usr/bin:$PATH
fails=0

# expect CODES DESCRIPTION -- COMMAND...: runs COMMAND, checks its exit code is one of CODES
# ("1" or "1|2").
expect() {
  local code=$1 what=$2
  shift 3
  "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  if [[ ! $rc =~ ^($code)$ ]]; then
    echo "FAIL: $what: exit $rc, expected $code"
    sed 's/^/  stderr: /' "$tmp/err" | tail -5
    fails=$((fails + 1))
  else
    echo "ok: $what (exit $rc)"
  fi
}
# stderr_has PATTERN DESCRIPTION
stderr_has() {
  if ! grep -q -- "$1" "$tmp/err"; then
    echo "FAIL: $2: stderr lacks '$1'"
    sed 's/^/  stderr: /' "$tmp/err" | tail -5
    fails=$((fails + 1))
  fi
}

# plotter_of PID: prints the PID of PID's child process running sysid_report.py (read from
# /proc, so no procps is needed); fails when there is none.
plotter_of() {
  local p f cmd
  for p in /proc/[0-9]*; do
    read -r -a f <"$p/stat" 2>/dev/null || continue
    [[ ${f[3]} == "$1" ]] || continue
    cmd=$(tr '\0' ' ' <"$p/cmdline" 2>/dev/null)
    [[ $cmd == *sysid_report.py* ]] && { echo "${p#/proc/}"; return 0; }
  done
  return 1
}

# file_has PATTERN FILE DESCRIPTION: FILE holds a line matching PATTERN.
file_has() {
  grep -q -- "$1" "$2" || { echo "FAIL: $3"; fails=$((fails + 1)); }
}
# absent PATH DESCRIPTION: PATH does not exist.
absent() {
  [[ -e $1 ]] && { echo "FAIL: $2"; fails=$((fails + 1)); }
  return 0
}
# exits_with PID CODE DESCRIPTION: waits for the background job PID, checks its exit code.
exits_with() {
  wait "$1"
  local rc=$?
  if [[ $rc -ne $2 ]]; then
    echo "FAIL: $3: exit $rc, expected $2"; cat "$tmp/err"; fails=$((fails + 1))
  else
    echo "ok: $3 exit $2"
  fi
}
# plotter_started PID: waits up to 60 s for fnmpc PID's sysid plotter and prints its PID;
# fails when fnmpc ends first or no plotter appears.
plotter_started() {
  local plotter
  for _ in $(seq 1 1200); do
    plotter=$(plotter_of "$1") && { echo "$plotter"; return 0; }
    kill -0 "$1" 2>/dev/null || return 1
    sleep 0.05
  done
  return 1
}

tri=$src/config/scenarios/triangle.yaml
# The triangle with its vehicle and sensors paths made absolute, to be edited in $tmp.
sed -e "s#\.\./vehicles/#$src/config/vehicles/#" -e "s#\.\./sensors/#$src/config/sensors/#" \
  "$tri" >"$tmp/tri.yaml"

# ---- CLI values.
expect 2 "--seed -5 refused" -- "$fnmpc" run "$tri" --seed -5 -o "$tmp/a"
expect 2 "-o '' refused" -- "$fnmpc" run "$tri" -o ''
for d in 0 -5 nan inf 200; do
  expect "1|2" "--duration $d refused" -- "$fnmpc" run "$tri" --duration "$d" -o "$tmp/d"
  stderr_has "duration" "--duration $d names the flag"
done
absent "$tmp/d" "a refused run created its folder"
# --duration keeps the scenario's landing allowance (the triangle's 82 - 73 = 9 s) after the
# leader's start at 12 s: 21 s and less are refused with the limit, nothing written.
expect "1" "--duration 21 refused (no flight before the landing allowance)" -- "$fnmpc" run "$tri" --duration 21 -o "$tmp/d"
stderr_has "landing allowance of 9 s" "--duration 21 names the allowance"
stderr_has "more than 21 s" "--duration 21 names the shortest duration"
absent "$tmp/d" "a refused --duration created its folder"
# Shortened scenarios with their own landing allowance and per-vehicle landing times land.
expect 0 "flying-leader-paper --duration 40 lands" -- "$fnmpc" run "$src/config/scenarios/flying-leader-paper.yaml" --duration 40 -q -o "$tmp/fl40"
expect 0 "follower-below-leader --duration 30 lands" -- "$fnmpc" run "$src/config/scenarios/follower-below-leader.yaml" --duration 30 -q -o "$tmp/fb30"

# ---- Compensation levels: an unknown one is refused; the level is recorded in
# summary.json at the top and per run, cooperative mode's link statistics too.
expect 1 "--compensation bogus refused" -- "$fnmpc" run "$tri" --compensation bogus -o "$tmp/c"
stderr_has "must be one of none, observer, wake, cooperative" "--compensation bogus lists the levels"
[[ -e "$tmp/c" ]] && { echo "FAIL: a refused run created its folder"; fails=$((fails + 1)); }
expect 0 "--compensation observer flies" -- "$fnmpc" run "$tri" --compensation observer --duration 26 -q -o "$tmp/obs"
for f in "$tmp/obs/summary.json" "$tmp/obs/run-01/summary.json"; do
  grep -q '"compensation": "observer"' "$f" || { echo "FAIL: $f lacks the level"; fails=$((fails + 1)); }
done
head -1 "$tmp/obs/run-01/follower1.csv" | grep -q ',est_fx,est_fy,est_fz$' ||
  { echo "FAIL: the CSV lacks est_f*"; fails=$((fails + 1)); }
expect 0 "--compensation cooperative flies" -- "$fnmpc" run "$tri" --compensation cooperative --duration 26 -q -o "$tmp/coop"
for f in "$tmp/coop/summary.json" "$tmp/coop/run-01/summary.json"; do
  grep -q '"compensation": "cooperative"' "$f" || { echo "FAIL: $f lacks the level"; fails=$((fails + 1)); }
  grep -Eq '"delivered": [1-9]' "$f" || { echo "FAIL: $f lacks delivered plans"; fails=$((fails + 1)); }
done
{ cat "$tmp/tri.yaml"; printf 'link:\n  loss_rate: 1.5\n'; } >"$tmp/badlink.yaml"
expect 1 "link.loss_rate 1.5 refused" -- "$fnmpc" run "$tmp/badlink.yaml" --compensation cooperative -o "$tmp/bl"
stderr_has "link.loss_rate" "the link error names the key"

# ---- Reused folder.
mkdir -p "$tmp/used" && echo stale >"$tmp/used/ghost.csv"
expect 1 "non-empty -o refused without --overwrite" -- "$fnmpc" run "$tri" -o "$tmp/used"
stderr_has "not empty" "refusal says why"
[[ -f "$tmp/used/ghost.csv" ]] || { echo "FAIL: refused run touched the folder"; fails=$((fails + 1)); }

# ---- Only regular files: /dev/zero is refused at once, no bad_alloc.
expect 1 "/dev/zero as scenario refused" -- timeout 20 "$fnmpc" run /dev/zero -o "$tmp/z"
stderr_has "not a regular file" "/dev/zero refusal"
expect 1 "/dev/zero as vehicle refused" -- timeout 20 "$fnmpc" check-vehicle /dev/zero
expect 1 "directory as vehicle refused" -- "$fnmpc" check-vehicle "$src/config"
stderr_has "is a directory" "directory refusal"

# ---- check-vehicle plausibility.
sed 's/^mass: 1.37/mass: 1e300/' "$src/config/vehicles/storm-drone-4.yaml" >"$tmp/heavy.yaml"
expect 1 "check-vehicle mass 1e300 refused" -- "$fnmpc" check-vehicle "$tmp/heavy.yaml"
stderr_has "key 'mass'" "mass refusal names the key"
expect 0 "check-vehicle shipped ok" -- "$fnmpc" check-vehicle "$src/config/vehicles/storm-drone-4.yaml"

# ---- Name with a path: refused at parse time, nothing written outside.
sed 's/^  - name: leader$/  - name: ..\/..\/pwned/' "$tmp/tri.yaml" >"$tmp/pwned.yaml"
expect 1 "vehicle name with a path refused" -- "$fnmpc" run "$tmp/pwned.yaml" -o "$tmp/p"
stderr_has "key 'vehicles\[0\].name'" "name refusal names the key"

# ---- report on an incomplete folder: one line, no traceback.
mkdir -p "$tmp/empty"
expect 1 "report on a folder without summary" -- "$fnmpc" report "$tmp/empty"
if grep -q Traceback "$tmp/err"; then echo "FAIL: report printed a traceback"; fails=$((fails + 1)); fi
mkdir -p "$tmp/half" && echo '{"complete": false, "stopped": "interrupted"}' >"$tmp/half/summary.json"
expect 1 "report on an interrupted folder" -- "$fnmpc" report "$tmp/half"
stderr_has "did not complete (interrupted)" "report says why"
[[ $(wc -l <"$tmp/err") -eq 1 ]] || { echo "FAIL: report printed more than one line"; cat "$tmp/err"; fails=$((fails + 1)); }
if grep -q Traceback "$tmp/err"; then echo "FAIL: report printed a traceback"; fails=$((fails + 1)); fi

# ---- sysid synth keeps an existing campaign.
mkdir -p "$tmp/campaign" && echo "name: mine" >"$tmp/campaign/campaign.yaml"
expect 1 "sysid synth refuses to overwrite a campaign" -- "$fnmpc" sysid synth "$tmp/campaign"
file_has "name: mine" "$tmp/campaign/campaign.yaml" "campaign overwritten"

# ---- A run that leaves its envelope exits 3 naming vehicle and reason.
sed 's/^metrics:/envelope: {max_altitude: 0.5}\nmetrics:/' "$tmp/tri.yaml" >"$tmp/env.yaml"
expect 3 "run leaving its envelope exits 3" -- "$fnmpc" run "$tmp/env.yaml" --duration 26 -q -o "$tmp/env"
stderr_has "vehicle leader: left the flight envelope" "failure names vehicle and reason"
file_has '"complete": true' "$tmp/env/summary.json" "summary not complete"

# ---- MuJoCo instability: a physically absurd but valid gust (1e8 m/s at 4 s; the
# drag of such a wind accelerates a vehicle beyond MuJoCo's 1e10 limit within a step, so
# MuJoCo warns "Nan, Inf or huge value in QACC/QVEL" and would reset the world). The run
# stops at that step with exit 4; stderr and summary.json give the time and the state.
# follower1's relative sensor reaches 2 m only, short of its neighbours at 2.5 m and 3 m: two
# warnings, printed and recorded in summary.json.
echo "relative: {max_range: 2.0}" >"$tmp/short-range.yaml"
# (The shipped triangle's own `reality: {}` line is replaced by this block.)
sed -e '/^reality:/d' -e 's/^metrics:/reality:\n  wake: false\n  wind:\n    discrete_gusts:\n      - {time: 4.0, duration: 1.0, amplitude: [1.0e8, 0.0, 0.0]}\nmetrics:/' \
  -e "/^  - name: follower1/a\\    sensors_file: $tmp/short-range.yaml" "$tmp/tri.yaml" >"$tmp/gust.yaml"
# Run from $tmp: MuJoCo's default warning handler would append to MUJOCO_LOG.TXT there; the
# simulator routes its warnings to stderr instead.
cd "$tmp" || exit 1
expect 4 "run whose simulator becomes unstable exits 4" -- "$fnmpc" run "$tmp/gust.yaml" --duration 26 -q -o "$tmp/gust"
cd - >/dev/null || exit 1
[ ! -e "$tmp/MUJOCO_LOG.TXT" ] || { echo "FAIL: MuJoCo wrote MUJOCO_LOG.TXT into the working directory"; fails=$((fails + 1)); }
stderr_has "MuJoCo warning: Nan, Inf or huge value in QACC" "MuJoCo's warning on stderr"
stderr_has "MuJoCo instability at t = 4" "instability message gives the time"
stderr_has "vehicle 0 position (" "instability message gives the state"
stderr_has "fnmpc run: warning: .*beyond the relative sensor's max_range" "unreachable neighbour warned"
file_has "beyond the relative sensor's max_range" "$tmp/gust/summary.json" "warning not recorded in summary.json"
file_has '"complete": false' "$tmp/gust/summary.json" "unstable run not marked incomplete"
file_has '"error": "\[World\] MuJoCo instability' "$tmp/gust/run-01/summary.json" "run summary lacks the error"
# The leader's CSV ends at the instability (no rows from a reset world after it).
last_t=$(tail -1 "$tmp/gust/run-01/leader.csv" | cut -d, -f1)
awk -v t="$last_t" 'BEGIN { exit !(t >= 3.9 && t <= 4.1) }' || { echo "FAIL: leader.csv ends at t = $last_t, expected about 4"; fails=$((fails + 1)); }

# ---- --overwrite deletes only what fnmpc wrote (its .fnmpc-manifest): a user's project
# folder that happens to hold a scenario.yaml and a summary.json is refused, nothing deleted.
mkdir -p "$tmp/project/src" && echo 'int main() {}' >"$tmp/project/src/main.cpp"
echo notes >"$tmp/project/notes.md" && cp "$tri" "$tmp/project/scenario.yaml" && echo '{}' >"$tmp/project/summary.json"
expect 1 "--overwrite refuses a folder fnmpc did not write" -- "$fnmpc" run "$tri" --overwrite --duration 26 -q -o "$tmp/project"
stderr_has "no .fnmpc-manifest" "refusal says why"
stderr_has "delete it yourself" "refusal says what to do"
for f in src/main.cpp notes.md scenario.yaml summary.json; do
  [[ -f $tmp/project/$f ]] || { echo "FAIL: refused --overwrite deleted $f"; fails=$((fails + 1)); }
done

# ---- SIGINT into a reused run folder with --overwrite: fnmpc's files deleted first (a file
# the user added stays), the run in progress stops after the current step, summaries
# "complete": false, exit 130. (--runs 50: still running after 5 s on any machine.)
cp -r "$tmp/obs" "$tmp/int" && echo mine >"$tmp/int/ghost.csv"
grep -q observer "$tmp/int/summary.json" || { echo "FAIL: the copied run folder"; fails=$((fails + 1)); }
"$fnmpc" run "$tri" -q --runs 50 --overwrite -o "$tmp/int" >"$tmp/out" 2>"$tmp/err" &
pid=$!
sleep 5
kill -INT $pid
exits_with $pid 130 "SIGINT"
file_has mine "$tmp/int/ghost.csv" "--overwrite deleted a file fnmpc did not write"
grep -q '"compensation": "observer"' "$tmp/int/run-01/summary.json" 2>/dev/null &&
  { echo "FAIL: --overwrite kept the earlier run"; fails=$((fails + 1)); }
file_has '"complete": false' "$tmp/int/summary.json" "interrupted summary not marked"
last=$(ls -d "$tmp"/int/run-* 2>/dev/null | sort | tail -1)
file_has '"stopped": "interrupted"' "$last/summary.json" "$last/summary.json not marked"
[[ -s "$last/leader.csv" ]] || { echo "FAIL: interrupted run lost its CSV"; fails=$((fails + 1)); }
ls "$last" | grep -q '\.part$' && { echo "FAIL: .part files left"; fails=$((fails + 1)); }
# SIGTERM likewise: exit 143, folder marked incomplete.
"$fnmpc" run "$tri" -q --runs 50 -o "$tmp/term" >"$tmp/out" 2>"$tmp/err" &
pid=$!
sleep 3
kill -TERM $pid
exits_with $pid 143 "SIGTERM"
stderr_has "interrupted (signal 15)" "SIGTERM stop says so"
file_has '"complete": false' "$tmp/term/summary.json" "terminated summary not marked"

# ---- merge: every shard checked before -o is touched; a refused merge leaves -o byte for
# byte, makes no folder, never prints a raw "filesystem error".
expect 0 "shard 0/2" -- "$fnmpc" run "$tri" --duration 26 --runs 2 --shard 0/2 --timing off -q -o "$tmp/m/s0"
expect 0 "shard 1/2" -- "$fnmpc" run "$tri" --duration 26 --runs 2 --shard 1/2 --timing off -q -o "$tmp/m/s1"
expect 0 "merge" -- "$fnmpc" merge "$tmp/m/s0" "$tmp/m/s1" -o "$tmp/m/out"
snapshot() { (cd "$1" && find . -type f -print0 | sort -z | xargs -0 sha256sum); }
snapshot "$tmp/m/out" >"$tmp/m/before"
no_raw_error() {
  grep -q "filesystem error" "$tmp/err" && { echo "FAIL: $1: raw filesystem error"; fails=$((fails + 1)); }
  return 0
}
cp -r "$tmp/m/s1" "$tmp/m/s1-cut"
truncate -s 2000 "$tmp/m/s1-cut/run-02/leader.csv"
expect 1 "merge of a truncated CSV refused" -- "$fnmpc" merge "$tmp/m/s0" "$tmp/m/s1-cut" -o "$tmp/m/out" --overwrite
stderr_has "run-02/leader.csv: 2000 bytes" "the refusal names the file"
no_raw_error "truncated CSV"
cp -r "$tmp/m/s0" "$tmp/m/s0-gone" && rm -r "$tmp/m/s0-gone/run-01"
expect 1 "merge of a shard without its run folder refused" -- "$fnmpc" merge "$tmp/m/s0-gone" "$tmp/m/s1" -o "$tmp/m/out" --overwrite
stderr_has "run-01/.*missing" "the refusal names the run folder"
no_raw_error "missing run folder"
expect 1 "merge into a new folder refused" -- "$fnmpc" merge "$tmp/m/s0-gone" "$tmp/m/s1" -o "$tmp/m/new"
absent "$tmp/m/new" "a refused merge made its folder"
snapshot "$tmp/m/s1" >"$tmp/m/s1-before"
expect 1 "merge into one of its shards refused" -- "$fnmpc" merge "$tmp/m/s0" "$tmp/m/s1" -o "$tmp/m/s1" --overwrite
stderr_has "its own input" "the refusal says why"
snapshot "$tmp/m/s1" | cmp -s - "$tmp/m/s1-before" || { echo "FAIL: a refused merge changed its shard"; fails=$((fails + 1)); }
snapshot "$tmp/m/out" | cmp -s - "$tmp/m/before" || { echo "FAIL: a refused merge changed -o"; fails=$((fails + 1)); }
# A write failing mid-merge (the file size limit stands in for a full disk: write() fails
# with EFBIG as it would with ENOSPC): exit 1 naming the file, -o as it was, nothing left.
expect 1 "merge failing on a write" -- bash -c 'trap "" XFSZ; ulimit -f 100; exec "$0" merge "$1" "$2" -o "$3" --overwrite' \
  "$fnmpc" "$tmp/m/s1" "$tmp/m/s0" "$tmp/m/out"
stderr_has "write failed: File too large; -o .* left as it was" "the failed write is named"
snapshot "$tmp/m/out" | cmp -s - "$tmp/m/before" || { echo "FAIL: a failed merge changed -o"; fails=$((fails + 1)); }
ls -a "$tmp/m" | grep -q '^\.out\.' && { echo "FAIL: a failed merge left its temporary folder"; fails=$((fails + 1)); }
expect 0 "merge --overwrite replaces an earlier merge" -- "$fnmpc" merge "$tmp/m/s1" "$tmp/m/s0" -o "$tmp/m/out" --overwrite
snapshot "$tmp/m/out" | cmp -s - "$tmp/m/before" || { echo "FAIL: the replaced merge differs"; fails=$((fails + 1)); }
ls -a "$tmp/m" | grep -q '^\.out\.' && { echo "FAIL: the merge left a temporary folder"; fails=$((fails + 1)); }

# ---- Inertia: principal moments no rigid body has (Izz > Ixx + Iyy) are refused at the key,
# by check-vehicle and by a scenario's --dry-run.
sed 's/^inertia: .*/inertia: [0.0123, 0.0136, 0.03]/' "$src/config/vehicles/storm-drone-4.yaml" >"$tmp/flat.yaml"
expect 1 "check-vehicle refuses an unrealisable inertia" -- "$fnmpc" check-vehicle "$tmp/flat.yaml"
stderr_has "flat.yaml:[0-9]*:[0-9]*: key 'inertia'" "the refusal names file, line and key"
stderr_has "triangle inequality" "the refusal says why"
sed "s#vehicle_file: .*#vehicle_file: $tmp/flat.yaml#" "$tmp/tri.yaml" >"$tmp/flat-tri.yaml"
expect 1 "--dry-run refuses an unrealisable inertia" -- "$fnmpc" run "$tmp/flat-tri.yaml" --dry-run
stderr_has "key 'inertia'" "the dry run names the key"

# ---- sysid and calibrate: glog never prints "Logging before
# InitGoogleLogging"; Ctrl-C during sysid's plotting stops the command with 130 and a message.
if "$fnmpc" sysid synth "$tmp/syn" >/dev/null 2>"$tmp/err"; then
  expect 0 "sysid on a synthetic campaign" -- "$fnmpc" sysid "$tmp/syn/campaign.yaml" -o "$tmp/syn/v.yaml" --no-plots
  if grep -q "InitGoogleLogging" "$tmp/err"; then echo "FAIL: sysid: glog 'Logging before InitGoogleLogging'"; fails=$((fails + 1)); fi
  # A flight without thrust commands leaves the thrust scale unobservable: Ceres' covariance
  # logs "Jacobian matrix is rank deficient" through glog (before glog was initialised this
  # came with "Logging before InitGoogleLogging() is written to STDERR").
  awk -F, -v OFS=, 'NR > 1 { $11 = 0 } 1' "$tmp/syn/flight.csv" >"$tmp/syn/no-thrust.csv"
  expect "0|3" "calibrate on a flight without thrust" -- "$fnmpc" calibrate "$tmp/syn/v.yaml" "$tmp/syn/no-thrust.csv" -o "$tmp/syn/cal.yaml" --no-plots
  stderr_has "rank deficient" "Ceres logged through glog"
  if grep -q "InitGoogleLogging" "$tmp/err"; then echo "FAIL: calibrate: glog 'Logging before InitGoogleLogging'"; fails=$((fails + 1)); fi
  # Ctrl-C reaches the whole foreground process group: fnmpc and its plotter. With job
  # control on (set -m) the background job gets its own process group and keeps SIGINT's
  # default action, as a job started from a terminal, so that group is signalled as a
  # terminal's Ctrl-C would.
  rm -rf "$tmp/syn/v.yaml" "$tmp/syn/v.yaml.report"
  set -m
  "$fnmpc" sysid "$tmp/syn/campaign.yaml" -o "$tmp/syn/v.yaml" >"$tmp/out" 2>"$tmp/err" &
  pid=$!
  set +m
  if ! plotter=$(plotter_started "$pid"); then
    echo "FAIL: the sysid plotter was never seen running"; fails=$((fails + 1)); wait $pid
  else
    kill -INT -- -"$pid"
    exits_with $pid 130 "SIGINT during sysid plotting"
    stderr_has "sysid_report.py interrupted (signal 2)" "interrupted plotting says so"
    absent "$tmp/syn/v.yaml" "interrupted sysid wrote its vehicle file"
    ls -d "$tmp"/syn/v.yaml.report* >/dev/null 2>&1 && { echo "FAIL: interrupted sysid left its report folder"; fails=$((fails + 1)); }
  fi
  # SIGTERM to fnmpc alone (kill PID): passed on to the plotter, exit 143 with a message.
  "$fnmpc" sysid "$tmp/syn/campaign.yaml" -o "$tmp/syn/v.yaml" >"$tmp/out" 2>"$tmp/err" &
  pid=$!
  if ! plotter=$(plotter_started "$pid"); then
    echo "FAIL: the sysid plotter was never seen running (SIGTERM case)"; fails=$((fails + 1)); wait $pid
  else
    kill -TERM "$pid"
    exits_with $pid 143 "SIGTERM during sysid plotting"
    stderr_has "sysid_report.py interrupted (signal 15)" "terminated plotting says so"
    kill -0 "$plotter" 2>/dev/null && { echo "FAIL: the plotter outlived fnmpc"; kill "$plotter"; fails=$((fails + 1)); }
    absent "$tmp/syn/v.yaml" "terminated sysid wrote its vehicle file"
  fi
else
  echo "FAIL: sysid synth failed"; sed 's/^/  stderr: /' "$tmp/err" | tail -5; fails=$((fails + 1))
fi

echo "cli_test: $fails failure(s)"
[[ $fails -eq 0 ]]
