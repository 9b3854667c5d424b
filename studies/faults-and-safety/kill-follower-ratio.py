#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Neighbour killed mid-flight (docs/results.md "Fault injection: neighbour killed mid-flight"):
the remaining follower's error to the leader after the killed neighbour left its cost, against
the fault-free flight with the same seed and plant.

    fnmpc campaign studies/faults-and-safety/kill-follower/killed-ideal.yaml -q
    fnmpc campaign studies/faults-and-safety/kill-follower/fault-free-ideal.yaml -q
    studies/faults-and-safety/kill-follower-ratio.py runs/kill-follower/killed-ideal/merged \
        runs/kill-follower/fault-free-ideal/merged

Per seed: when the follower dropped the killed vehicle (summary.json
faults.kill_controller.followers.<follower>.dropped_from_cost_s), the mean of the CSV column
`err0` (its error to the leader, the first neighbour) over the steady-state samples (`steady`
= 1) from that time on, in both flights, and their ratio (the figure of docs/results.md); the same
split into the first steady-state window after the drop and the later ones (the return from
where the departing neighbour pulled it, and the flight after it); its largest error to the
leader after the kill."""
import argparse
import csv
import json
import os
import sys


def rows(folder, run, vehicle):
    with open(os.path.join(folder, run, vehicle + '.csv'), newline='') as f:
        return list(csv.DictReader(f))


def mean(v):
    return sum(v) / len(v) if v else float('nan')


def windows(r, t0):
    """Steady-state samples of err0 from t0 on, as contiguous windows."""
    out, cur = [], None
    for q in r:
        if q['steady'] == '1' and float(q['t']) >= t0 - 1e-9:
            if cur is None:
                cur = []
                out.append(cur)
            cur.append(float(q['err0']))
        else:
            cur = None
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('killed', help='fnmpc run output folder of the kill-follower scenario')
    ap.add_argument('reference', help='fault-free output folder, same seeds and plant')
    ap.add_argument('--follower', default='follower1', help='the remaining follower')
    a = ap.parse_args()
    runs = sorted(d for d in os.listdir(a.killed) if d.startswith('run-'))
    print('| seed | dropped at [s] | fault-free [m] | killed [m] | ratio | first window: '
          'fault-free / killed [m] | later windows: fault-free / killed [m] | ratio later | '
          'max error after the kill [m] |')
    print('|---|---|---|---|---|---|---|---|---|')
    for run in runs:
        with open(os.path.join(a.killed, run, 'summary.json')) as f:
            fault = json.load(f)['faults']['kill_controller']
        info = fault['followers'][a.follower]
        drop = info['dropped_from_cost_s']
        if drop is None:
            print(f'| {run} | never dropped | | | | | | | |')
            continue
        k, ref = rows(a.killed, run, a.follower), rows(a.reference, run, a.follower)
        wk, wr = windows(k, drop), windows(ref, drop)
        if len(wk) != len(wr) or not wk:
            sys.exit(f'{run}: the steady-state windows of the two flights differ')
        fk, fr = mean([e for w in wk for e in w]), mean([e for w in wr for e in w])
        lk, lr = mean([e for w in wk[1:] for e in w]), mean([e for w in wr[1:] for e in w])
        worst = info['formation_error']['leader']['max_after_kill_m']
        print(f'| {int(run[4:])} | {drop:.2f} | {fr:.4f} | {fk:.4f} | {fk / fr:.2f} | '
              f'{mean(wr[0]):.4f} / {mean(wk[0]):.4f} | {lr:.4f} / {lk:.4f} | {lk / lr:.2f} | '
              f'{worst:.2f} |')


if __name__ == '__main__':
    main()
