#!/usr/bin/env bash
# A LOD chain's time against one run at its coarsest rate (issue "what pipelines ask for": at most 1.35x),
# alternating runs, best of N each, on make_volume noise -n SIZE (default 192: 1.19M faces).
# Usage: benchmarks/lods.sh [SIZE] [N]
set -euo pipefail
cd "$(dirname "$0")/.."
S=${1:-192}; N=${2:-3}
./scripts/build.sh > /dev/null
B=build; W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
"$B/make_volume" noise -n "$S" -o "$W/v.vdb" > /dev/null
best() { awk -v a="$1" -v b="$2" 'BEGIN { print (a == "" || b < a) ? b : a }'; }
ONE=""; CHAIN=""
for ((k = 0; k < N; k++)); do
  /usr/bin/time -f "%e" -o "$W/t" "$B/vdb_isosimp" "$W/v.vdb" -q -r 0.01 -o "$W/one.ply"; ONE=$(best "$ONE" "$(cat "$W/t")")
  /usr/bin/time -f "%e" -o "$W/t" "$B/vdb_isosimp" "$W/v.vdb" -q --lods 0.2,0.05,0.01 -o "$W/chain.ply"; CHAIN=$(best "$CHAIN" "$(cat "$W/t")")
done
awk -v c="$CHAIN" -v o="$ONE" 'BEGIN { printf "--lods 0.2,0.05,0.01: %.2f s; -r 0.01 alone: %.2f s; ratio %.2f (target <= 1.35)\n", c, o, c / o }'
