#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The main job on a fresh machine: installs the Debian packages, builds fnmpc in Release,
# flies the reference simulation experiment (config/scenarios/triangle.yaml: one leader
# through six waypoints, two followers keeping a triangle from relative sensing only) in
# the MuJoCo simulator with every sensor and estimator in the loop, and writes the report
# (PNG plots + report.html + summary.json + the 3-D replay.html). Opens nothing.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)" --target fnmpc
RUN_DIR=out/triangle
rm -rf "$RUN_DIR"
./build/apps/fnmpc/fnmpc run config/scenarios/triangle.yaml -o "$RUN_DIR"
./build/apps/fnmpc/fnmpc report "$RUN_DIR"
echo
echo "main job: run folder $RUN_DIR"
echo "  metrics: $RUN_DIR/summary.json"
echo "  report:  $RUN_DIR/report.html (plots: $RUN_DIR/*.png, logs: $RUN_DIR/run-01/*.csv)"
echo "  replay:  $RUN_DIR/replay.html (interactive 3-D replay, opens offline in a browser)"
