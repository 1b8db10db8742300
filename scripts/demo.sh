#!/usr/bin/env bash
# Fresh machine to first mesh: install dependencies, build, simplify the bundled example volume.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/deps.sh
./scripts/build.sh
mkdir -p out
./build/vdb_isosimp examples/data/noise_fog.vdb --ratio 0.2 -o out/noise_fog.ply --report out/noise_fog.json
echo "mesh written to: $(pwd)/out/noise_fog.ply (report: out/noise_fog.json)"
