#!/bin/bash
# SPDX-License-Identifier: BSD-3-Clause
# The campaign of docs/results.md "Beating the wake": every shipped scenario flown with the four
# compensation levels (10 seeds each, reality as the scenario ships it), plus cooperative mode on
# a lossy link (30 % loss, 100 ms latency) and the flying leader on 2 s legs. Run from the
# repository root; a folder that already has its summary.json is kept (resumable).
#   studies/compensation/compensation-campaign.sh [FNMPC] [OUT] [ONLY]  (defaults: build/apps/fnmpc/fnmpc, runs/coop)
# ONLY (optional): an extended regular expression; only the folders whose name (e.g.
# stress-wedge10-fast-wake) matches it are flown (one campaign at a time on a shared machine).
# RUNS (environment, default 10): seeds 1..RUNS per folder (fewer for the large scale/ ones).
#   studies/compensation/compensation-table.py runs/coop/triangle-{none,observer,wake,cooperative,lossy}
set -u
F=${1:-build/apps/fnmpc/fnmpc}
R=${2:-runs/coop}
ONLY=${3:-}
RUNS=${RUNS:-10}
mkdir -p "$R"
run() { # folder scenario level
  [[ -f $R/$1/summary.json ]] && return
  [[ -n $ONLY && ! $1 =~ $ONLY ]] && return
  rm -rf "${R:?}/$1"
  "$F" run "$2" --runs "$RUNS" --compensation "$3" -q -o "$R/$1" >/dev/null 2>"$R/$1.err"
  echo "$(date +%T) $1 exit $?" >>"$R/progress.log"
}
# Variants (vehicle and sensor paths made absolute): the flying leader on 2 s legs, and
# the lossy link.
sed -e "s#\.\./#$PWD/config/#" -e 's/^  leg_duration: 4.0/  leg_duration: 2.0/' \
  config/scenarios/flying-leader-paper.yaml >"$R/flying-leader-2s.yaml"
for sc in follower-below-leader flying-leader-paper triangle manual-leader; do
  { sed -e "s#\.\./#$PWD/config/#" "config/scenarios/$sc.yaml"
    printf 'link: {loss_rate: 0.3, latency: 0.1}\n'; } >"$R/$sc-lossy.yaml"
done
{ cat "$R/flying-leader-2s.yaml"; printf 'link: {loss_rate: 0.3, latency: 0.1}\n'; } \
  >"$R/flying-leader-2s-lossy.yaml"
for sc in follower-below-leader flying-leader-paper flying-leader-2s triangle manual-leader; do
  file=config/scenarios/$sc.yaml
  [[ $sc == flying-leader-2s ]] && file=$R/flying-leader-2s.yaml
  for c in none observer wake cooperative; do run "$sc-$c" "$file" $c; done
  run "$sc-lossy" "$R/$sc-lossy.yaml" cooperative
done
for f in config/scenarios/stress/*.yaml config/scenarios/scale/*.yaml; do
  sc=$(basename "$(dirname "$f")")-$(basename "$f" .yaml)
  for c in none observer wake cooperative; do run "$sc-$c" "$f" $c; done
done
