#!/usr/bin/env bash
# Installs dependencies, builds, and runs the whole default test suite with ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/deps.sh
./scripts/build.sh
cd build
ctest --output-on-failure -j"$(nproc)" --timeout 900
