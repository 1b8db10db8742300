#!/usr/bin/env bash
# Scale-out (issue "beyond one machine"): threads and MPI ranks on the CT-like noise volume, and the
# merge tree's modelled speed-up for 1-256 workers from the measured seconds of every slab and join.
# Usage: benchmarks/scale.sh [SIZE] [--gyroid]
#   SIZE      noise volume edge (default 448: 18.3M faces at full resolution)
#   --gyroid  also the 250M-face gyroid (make_volume gyroid-band 1024^3, period 42; ~2 GB, cached)
#   PERF_WORK=DIR keeps volumes and reports there; BASE=path/to/vdb_isosimp compares RMS and peak RSS
#   with another build (same run). Writes the model's plot to SVG=path (default docs/scale.svg).
set -euo pipefail
cd "$(dirname "$0")/.."
N=448; GYROID=0
for a in "$@"; do case "$a" in --gyroid) GYROID=1 ;; *) N=$a ;; esac; done
./scripts/deps.sh > /dev/null
./scripts/build.sh -DVDB_ISOSIMP_BUILD_BENCHMARKS=ON > /dev/null
B=build; W=${PERF_WORK:-$(mktemp -d)}; mkdir -p "$W"
[ -z "${PERF_WORK:-}" ] && trap 'rm -rf "$W"' EXIT
SVG=${SVG:-docs/scale.svg}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
RANKS=16  # the many-rank run whose messages the model's transfers are fitted to
field() { sed -n "s/.*\"$1\": *\([0-9.e+-]*\).*/\1/p" "$2" | head -1; }
rms() { "$B/mesh_error" "$1" "$2" --json | tr -d '\n' | sed -n 's/.*"a_to_b": *{[^}]*"rms_pct": *\([0-9.e+-]*\).*/\1/p'; }
timed() { /usr/bin/time -f "%e %M" -o "$W/time.txt" "$@"; read -r SEC KB < "$W/time.txt"; MB=$((KB / 1024)); }
minof() { awk -v a="$1" -v b="$2" 'BEGIN { print (a == "" || b < a) ? b : a }'; }

[ -f "$W/noise$N.vdb" ] || "$B/make_volume" noise -n "$N" -o "$W/noise$N.vdb" > /dev/null
V="$W/noise$N.vdb"; ISO=0.3
[ -f "$W/full$N.ply" ] || "$B/vdb_isosimp" "$V" --iso $ISO -r 1 -q -o "$W/full$N.ply"
MODEL=()
for R in 0.2 0.02; do
  # Alternating runs, fastest of two each: 1 thread, 2 threads, mpirun 1 x 1 and 2 x 1.
  T1=""; T2=""; M1=""; M2=""
  for k in 1 2; do
    timed "$B/vdb_isosimp" "$V" --iso $ISO -r $R -j 1 -q -o "$W/j1.ply" --report "$W/j1_$R.json"; T1=$(minof "$T1" "$SEC"); W1=$SEC
    timed "$B/vdb_isosimp" "$V" --iso $ISO -r $R -j 2 -q -o "$W/j2.ply" --report "$W/j2_$R.json"; T2=$(minof "$T2" "$SEC"); RSS2=$MB
    timed mpirun -np 1 "$B/vdb_isosimp" "$V" --iso $ISO -r $R -j 1 -q -o "$W/n1.ply"; M1=$(minof "$M1" "$SEC")
    timed mpirun -np 2 "$B/vdb_isosimp" "$V" --iso $ISO -r $R -j 1 -q -o "$W/n2.ply" --report "$W/n2_$R.json"; M2=$(minof "$M2" "$SEC")
  done
  # The model's messages: 16 ranks send 15, of subtrees from a few slabs to half the tree (one run: only
  # their bytes are read).
  mpirun -np $RANKS "$B/vdb_isosimp" "$V" --iso $ISO -r $R -j 1 -q -o "$W/n$RANKS.ply" --report "$W/n${RANKS}_$R.json"
  for f in j2 n1 n2 n$RANKS; do cmp -s "$W/j1.ply" "$W/$f.ply" || { echo "FAIL: $f wrote other bytes than 1 thread"; exit 1; }; done
  echo "noise ${N}^3 R=$R: $(field faces_full "$W/j1_$R.json") -> $(field faces_out "$W/j1_$R.json") faces, $(field slabs "$W/j1_$R.json") slabs, RMS $(rms "$W/full$N.ply" "$W/j1.ply") % (same bytes in all four modes)"
  awk -v t1=$T1 -v t2=$T2 -v m1=$M1 -v m2=$M2 -v rss=$RSS2 'BEGIN {
    printf "  1 thread %.1f s, 2 threads %.1f s (%.2fx); mpirun 1 x 1 %.1f s, 2 x 1 %.1f s (%.2fx); peak RSS (2 threads) %d MB\n", t1, t2, t1/t2, m1, m2, m1/m2, rss }'
  echo "  bytes sent by rank 1: $(sed -n 's/.*"rank_bytes_sent": *\[[^,]*, *\([0-9.e+]*\).*/\1/p' "$W/n2_$R.json"), rank seconds $(sed -n 's/.*"rank_seconds": *\(\[[^]]*\]\).*/\1/p' "$W/n2_$R.json")"
  if [ -n "${BASE:-}" ]; then
    timed "$BASE" "$V" --iso $ISO -r $R -j 2 -q -o "$W/base.ply"
    echo "  BASE: $SEC s, peak RSS $MB MB, RMS $(rms "$W/full$N.ply" "$W/base.ply") %"
  fi
  MODEL+=(--messages "$W/n${RANKS}_$R.json" "$W/j1_$R.json" "$W1" "noise ${N}^3 R=$R")
done
if [ "$GYROID" = 1 ]; then
  GV="$W/gyroid-band1024p42.vdb"
  [ -f "$GV" ] || "$B/make_volume" gyroid-band -n 1024 --period 42 -o "$GV" > /dev/null
  timed "$B/vdb_isosimp" "$GV" -f 1000000 -j 2 -q -o "$W/gyroid.ply" --report "$W/gyroid.json"
  echo "gyroid 1024^3: $(field faces_full "$W/gyroid.json") -> $(field faces_out "$W/gyroid.json") faces, $(field slabs "$W/gyroid.json") slabs, 2 threads $SEC s, peak RSS $MB MB"
  # Per-node seconds from one thread (no contention between threads), messages from 16 ranks.
  timed "$B/vdb_isosimp" "$GV" -f 1000000 -j 1 -q -o "$W/gyroid1.ply" --report "$W/gyroid1.json"; GW=$SEC
  mpirun -np $RANKS "$B/vdb_isosimp" "$GV" -f 1000000 -j 1 -q -o "$W/gyroid$RANKS.ply" --report "$W/gyroid$RANKS.json"
  for f in gyroid1 gyroid$RANKS; do cmp -s "$W/gyroid.ply" "$W/$f.ply" || { echo "FAIL: $f wrote other bytes than 2 threads"; exit 1; }; done
  MODEL+=(--messages "$W/gyroid$RANKS.json" "$W/gyroid1.json" "$GW" "gyroid 250M faces, 1M kept")
fi
echo
/usr/bin/python3 benchmarks/scale_model.py "${MODEL[@]}" "$SVG"
