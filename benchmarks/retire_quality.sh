#!/usr/bin/env bash
# What retiring joined nodes' interiors (--retire-above) costs in quality on hard content: csg and
# dodecahedron level sets at 384^3 (default slabs) at R = 0.2 and 0.05, each with --retire-above 0, 100000
# and the default 50000. Prints RMS % of the diagonal (mesh_error, full -> ours), the faces retired, and
# whether every mesh is closed, manifold and oriented without zero-area faces.
# Usage: benchmarks/retire_quality.sh [SIZE]   (default 384; about 2 minutes on 2 cores)
#   RETIRE_WORK=DIR  keep the volumes and meshes there (generated volumes are reused)
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-384}
./scripts/build.sh > /dev/null
B=build; W=${RETIRE_WORK:-$(mktemp -d)}; mkdir -p "$W"
[ -z "${RETIRE_WORK:-}" ] && trap 'rm -rf "$W"' EXIT
field() { sed -n "s/.*\"$1\": *\([0-9.e+-]*\).*/\1/p" "$2" | head -1; }
rms() { "$B/mesh_error" "$1" "$2" --json | tr -d '\n' | sed -n 's/.*"a_to_b": *{[^}]*"rms_pct": *\([0-9.e+-]*\).*/\1/p'; }
echo "| volume | R | faces out | RMS %, 0 | 100000 | 50000 | faces retired at 50000 | all clean |"
echo "|---|---|---|---|---|---|---|---|"
for v in csg dodecahedron; do
  [ -f "$W/$v.vdb" ] || "$B/make_volume" "$v" -n "$N" -o "$W/$v.vdb" > /dev/null
  [ -f "$W/${v}_full.ply" ] || "$B/vdb_isosimp" "$W/$v.vdb" -r 1 -q -o "$W/${v}_full.ply"
  for r in 0.2 0.05; do
    row="| $v $N³ | $r |"; clean=yes
    for t in 0 100000 50000; do
      "$B/vdb_isosimp" "$W/$v.vdb" -r "$r" --retire-above "$t" -q -o "$W/out.ply" --report "$W/out.json"
      [ "$t" = 0 ] && row="$row $(field faces_out "$W/out.json") |"
      row="$row $(rms "$W/${v}_full.ply" "$W/out.ply") |"
      "$B/mesh_stats" "$W/out.ply" | grep -q 'closed / manifold / oriented *yes / yes / yes' || clean=no
      "$B/mesh_stats" "$W/out.ply" | grep -q 'zero-area faces *0 ' || clean=no
    done
    echo "$row $(field faces_retired "$W/out.json") | $clean |"
  done
done
