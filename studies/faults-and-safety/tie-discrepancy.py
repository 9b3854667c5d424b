#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Formation discrepancy between a follower's two neighbours, from the truth columns of a
`fnmpc run` output folder (docs/safety.md "A neighbour leaving the formation"): for each
follower that has the leader and one other vehicle j among its first two neighbours,

    e(t) = (rel_j - d_j) - (rel_leader - d_leader)

(j's formation error relative to the leader, what the follower can observe without
communication; d from the mean of rel over the steady-state samples before --before), and
whether a rule "|e| > HEIGHT and moving away faster than SPEED, held for TIME" would trip,
with two meanings of moving away: `growth` = d|e|/dt, `away` = j's own velocity along e
(0.2 s averages). Prints per run and follower: the largest |e| and its vertical part in the
NMPC phase, and the first time each rule trips (none: never).

    studies/faults-and-safety/tie-discrepancy.py /tmp/kf5 --before 26.5 --height 0.3 --speed 0.3 --time 0.3"""
import argparse
import csv
import glob
import os

import numpy as np


def column(r, k):
    return np.array([float(q[k]) if q[k] not in ('', 'nan') else np.nan for q in r])


def vec(r, prefix):
    return np.c_[column(r, prefix + 'x'), column(r, prefix + 'y'), column(r, prefix + 'z')]


def first_held(t, cond, hold):
    since = None
    for ti, c in zip(t, cond):
        if not c:
            since = None
            continue
        since = ti if since is None else since
        if ti - since >= hold - 1e-9:
            return ti
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('folder')
    ap.add_argument('--before', type=float, default=float('inf'),
                    help='[s] desired offsets from the steady-state samples before this time')
    ap.add_argument('--height', type=float, default=0.3, help='[m]')
    ap.add_argument('--speed', type=float, default=0.3, help='[m/s]')
    ap.add_argument('--time', type=float, default=0.3, help='[s]')
    a = ap.parse_args()
    for run in sorted(glob.glob(os.path.join(a.folder, 'run-*'))):
        with open(os.path.join(run, 'leader.csv'), newline='') as f:
            leader = vec(list(csv.DictReader(f)), '')
        for path in sorted(glob.glob(os.path.join(run, '*.csv'))):
            if path.endswith('leader.csv'):
                continue
            with open(path, newline='') as f:
                r = list(csv.DictReader(f))
            if 'rel1_x' not in r[0]:
                continue
            t = column(r, 't')
            p = vec(r, '')
            rel = [vec(r, f'rel{n}_') for n in (0, 1)]
            lead = [n for n in (0, 1) if np.nanmin(np.abs(rel[n] - (leader[:len(p)] - p))) < 1e-6
                    and np.nanmax(np.abs(rel[n] - (leader[:len(p)] - p))) < 1e-3]
            if not lead:
                continue
            lead = lead[0]
            j = 1 - lead
            nmpc = np.array([q['phase'] == 'nmpc' for q in r])
            ref = (column(r, 'steady') == 1) & (t < a.before)
            if not ref.any():
                print(f'{os.path.basename(run)} {os.path.basename(path)[:-4]}: no steady-state '
                      'samples for the desired offsets')
                continue
            e = (rel[j] - np.nanmean(rel[j][ref], axis=0)) - (rel[lead] -
                                                               np.nanmean(rel[lead][ref], axis=0))
            dt = t[1] - t[0]
            k = max(1, int(round(0.2 / dt)))
            smooth = np.ones(k) / k

            def rate(x):
                d = np.gradient(x, dt, axis=0)
                return np.c_[[np.convolve(d[:, i], smooth, 'same') for i in range(3)]].T

            n = np.linalg.norm(e, axis=1)
            unit = e / np.maximum(n, 1e-9)[:, None]
            growth = np.sum(rate(e) * unit, axis=1)
            away = np.sum(rate(p + rel[j]) * unit, axis=1)
            big = nmpc & (n > a.height)
            trips = [first_held(t, big & (s > a.speed), a.time) for s in (growth, away)]
            fmt = ['none' if x is None else f'{x:.2f} s' for x in trips]
            print(f'{os.path.basename(run)} {os.path.basename(path)[:-4]}: max |e| '
                  f'{np.nanmax(np.where(nmpc, n, 0)):.2f} m (vertical '
                  f'{np.nanmax(np.where(nmpc, np.abs(e[:, 2]), 0)):.2f} m); |e| > {a.height} m '
                  f'and growth > {a.speed} m/s for {a.time} s: {fmt[0]}; away: {fmt[1]}')


if __name__ == '__main__':
    main()
