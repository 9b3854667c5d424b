#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The main job on a fresh machine: installs the Debian packages, builds fnmpc in
# Release and runs the solver benchmark of shared/benchmark/ocp-spec.md, writing
# its table to out/bench.txt and out/bench.json.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)"
mkdir -p out
./build/apps/fnmpc/fnmpc bench | tee out/bench.txt
./build/apps/fnmpc/fnmpc bench --json > out/bench.json
echo "main job: wrote out/bench.txt and out/bench.json"
