#!/usr/bin/env bash
# Ours against full extraction + OpenMesh's decimator on generated volumes (a level set and a fog volume
# with many components), at R = 0.2 and 0.02: faces, seconds, peak RSS and RMS error (full surface
# sampled onto the simplified one, % of the bounding-box diagonal), with ratios ours / baseline measured
# in the same run. Usage: benchmarks/memory_quality.sh [SIZE]   (default 256: ~1-2M faces)
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-256}
./scripts/deps.sh
./scripts/build.sh -DVDB_ISOSIMP_BUILD_BENCHMARKS=ON > /dev/null
B=build; W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
$B/make_volume torus -n "$N" -o "$W/torus.vdb" > /dev/null
$B/make_volume noise -n "$N" -o "$W/noise.vdb" > /dev/null
field() { sed -n "s/.*\"$1\": \([0-9.e+-]*\).*/\1/p" "$2" | head -1; }
echo "| volume | R | faces full | faces out | ours s | openmesh s | ours RSS MB | openmesh RSS MB | RSS ratio | ours RMS % | openmesh RMS % | RMS ratio |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for vol in torus noise; do
  $B/vdb_isosimp "$W/$vol.vdb" -r 1 -q -o "$W/$vol.full.ply"
  for R in 0.2 0.02; do
    $B/vdb_isosimp "$W/$vol.vdb" -r $R -q -o "$W/ours.ply" --report "$W/ours.json"
    FO=$(field faces_out "$W/ours.json")
    $B/baseline_openmesh "$W/$vol.vdb" -f "$FO" -o "$W/om.ply" > "$W/om.json"
    EO=$($B/mesh_error "$W/$vol.full.ply" "$W/ours.ply" --json | tr -d '\n')
    EM=$($B/mesh_error "$W/$vol.full.ply" "$W/om.ply" --json | tr -d '\n')
    rms() { echo "$1" | sed -n 's/.*"a_to_b": *{[^}]*"rms_pct": *\([0-9.e+-]*\).*/\1/p'; }
    RO=$(rms "$EO"); RM=$(rms "$EM")
    awk -v v=$vol -v r=$R -v ff="$(field faces_full "$W/ours.json")" -v fo=$FO \
        -v ts="$(field seconds "$W/ours.json")" -v tm="$(field seconds "$W/om.json")" \
        -v mo="$(field peak_rss_mb "$W/ours.json")" -v mm="$(field peak_rss_mb "$W/om.json")" -v ro="$RO" -v rm="$RM" \
        'BEGIN { printf "| %s | %s | %d | %d | %.2f | %.2f | %.0f | %.0f | %.2f | %.5f | %.5f | %.3f |\n", v, r, ff, fo, ts, tm, mo, mm, mo/mm, ro, rm, ro/rm }'
  done
done
