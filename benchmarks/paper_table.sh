#!/usr/bin/env bash
# The paper's comparison (Hou & Chen, section 5: Table 3, Figures 5, 7 and 9), reproduced on this
# machine. Builds with the baselines, generates four volumes (level-set torus, CT-like noise fog,
# gyroid fog, a 2x trilinear up-sampling of a smaller noise volume), runs ours and every baseline at
# R = 0.2 and R = 0.02, measures the RMS error of each result against the full-resolution surface
# (mesh_error: the full surface sampled onto the simplified one, % of the bounding-box diagonal),
# and writes OUTDIR/paper_table.md and the plots OUTDIR/paper_fig*.png.
#
# Usage: benchmarks/paper_table.sh [--quick] [OUTDIR]     (default OUTDIR: docs)
#   --quick: small volumes and a short B sweep, to check the script (minutes, not for the record).
# Needs about 16 minutes on 2 cores (plus the build); run nothing else heavy meanwhile.
set -euo pipefail
cd "$(dirname "$0")/.."
QUICK=0
if [ "${1:-}" = "--quick" ]; then QUICK=1; shift; fi
OUT=${1:-docs}
mkdir -p "$OUT"
if [ $QUICK = 1 ]; then COMMAND="benchmarks/paper_table.sh --quick $OUT"; else COMMAND="benchmarks/paper_table.sh $OUT"; fi
START=$(date +%s)
LOAD_START=$(cut -d' ' -f1-3 /proc/loadavg)

./scripts/deps.sh
# Plots: Debian's matplotlib for Debian's python3 (only this benchmark needs it).
if ! dpkg-query -W -f='${Status}' python3-matplotlib 2>/dev/null | grep -q "install ok installed"; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "installing: python3-matplotlib"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends python3-matplotlib
fi
# PAPER_TABLE_BUILD_DIR=dir: use programs already built there instead of building into build/.
if [ -n "${PAPER_TABLE_BUILD_DIR:-}" ]; then
  B=$PAPER_TABLE_BUILD_DIR
else
  ./scripts/build.sh -DVDB_ISOSIMP_BUILD_BENCHMARKS=ON
  B=build
fi
BUILD_END=$(date +%s)
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
# PAPER_TABLE_RESULTS=dir: keep the raw results (JSON, CSV) there.
R_DIR=${PAPER_TABLE_RESULTS:-$W/results}; mkdir -p "$R_DIR"

# Volumes. Sizes give 1.2-1.25M full-resolution faces each: the in-core and cascade baselines (OpenMesh,
# ~40 us per collapse) then fit the 30-minute budget on 2 cores.
if [ $QUICK = 1 ]; then
  TORUS=192; NOISE=96; GYROID=64; SMALL=64; BATCHES="4000 16000 64000"; TRACE_B="4000 64000"
else
  TORUS=600; NOISE=190; GYROID=150; SMALL=124; BATCHES="4000 8000 16000 32000 64000 128000 256000 512000"; TRACE_B="8000 128000"
fi
$B/make_volume torus  -n $TORUS  -o "$W/torus.vdb"  > /dev/null
$B/make_volume noise  -n $NOISE  -o "$W/noise.vdb"  > /dev/null
$B/make_volume gyroid -n $GYROID -o "$W/gyroid.vdb" > /dev/null
$B/make_volume noise  -n $SMALL  -o "$W/small.vdb"  > /dev/null
$B/upsample_volume "$W/small.vdb" -f 2 -o "$W/noise_x2.vdb" > /dev/null
cat > "$R_DIR/sets.txt" <<EOF
torus	level-set torus (make_volume torus -n $TORUS)	${TORUS}^3
noise	CT-like noise fog, many components (make_volume noise -n $NOISE)	${NOISE}^3
gyroid	gyroid fog, surface fills the box (make_volume gyroid -n $GYROID)	${GYROID}^3
noise_x2	noise fog $SMALL^3 up-sampled 2x, trilinear (upsample_volume -f 2)	$((2 * SMALL))^3
EOF
SETS="torus noise gyroid noise_x2"

# run NAME CMD...: wall seconds and max RSS (KiB) of the process in NAME.time, stdout in NAME.out.
run() {
  local name=$1; shift
  /usr/bin/time -f "%e %M" -o "$R_DIR/$name.time" "$@" > "$R_DIR/$name.out"
}
# err NAME MESH FULL: mesh_error (full sampled onto MESH) and mesh_stats of MESH.
err() {
  $B/mesh_error --json "$3" "$2" > "$R_DIR/$1.err"
  $B/mesh_stats --json "$2" > "$R_DIR/$1.stats"
}

for s in $SETS; do
  echo "== $s"
  V=$W/$s.vdb; FULL=$W/$s.full.ply
  run "$s.full" $B/vdb_isosimp "$V" -r 1 -q -o "$FULL" --report "$R_DIR/$s.full.report"
  # OpenVDB's own full extraction against ours: the error floor of the volumeToMesh baselines.
  run "$s.vdbfull" $B/baseline_meshopt "$V" -r 1 -o "$W/m.ply"
  err "$s.vdbfull" "$W/m.ply" "$FULL"
  for R in 0.2 0.02; do
    echo "   R = $R"
    run "$s.$R.ours" $B/vdb_isosimp "$V" -r $R -q -o "$W/m.ply" --report "$R_DIR/$s.$R.ours.report" \
        --trace "$R_DIR/$s.$R.ours.trace"
    err "$s.$R.ours" "$W/m.ply" "$FULL"
    run "$s.$R.openmesh" $B/baseline_openmesh "$V" -r $R -o "$W/m.ply"
    err "$s.$R.openmesh" "$W/m.ply" "$FULL"
    run "$s.$R.cascade" $B/baseline_cascade "$V" -r $R -o "$W/m.ply" --tmpdir "$W"
    err "$s.$R.cascade" "$W/m.ply" "$FULL"
    run "$s.$R.meshopt" $B/baseline_meshopt "$V" -r $R -o "$W/m.ply"
    err "$s.$R.meshopt" "$W/m.ply" "$FULL"
    run "$s.$R.meshopt_ours" $B/baseline_meshopt "$V" -r $R --extract ours -o "$W/m.ply"
    err "$s.$R.meshopt_ours" "$W/m.ply" "$FULL"
    run "$s.$R.vdbadaptive" $B/baseline_vdbadaptive "$V" -r $R -o "$W/m.ply"
    err "$s.$R.vdbadaptive" "$W/m.ply" "$FULL"
  done
  [ "$s" = noise ] || rm -f "$FULL"
done

# Figure 7: error and time against B at R = 0.1 and 0.01 (CT-like noise, as the paper's bunny);
# Figure 5: intermediate mesh size per decimation for two values of B (traces of two of these runs).
echo "== B sweep (noise)"
for R in 0.1 0.01; do
  for b in $BATCHES; do
    run "sweep.$R.$b" $B/vdb_isosimp "$W/noise.vdb" -r $R -b $b -q -o "$W/m.ply" \
        --report "$R_DIR/sweep.$R.$b.report" --trace "$R_DIR/sweep.$R.$b.trace"
    $B/mesh_error --json "$W/noise.full.ply" "$W/m.ply" > "$R_DIR/sweep.$R.$b.err"
  done
done

END=$(date +%s)
/usr/bin/python3 benchmarks/paper_table.py "$R_DIR" "$OUT" --command "$COMMAND" \
  --sweep "$BATCHES" --trace-batches "$TRACE_B" --seconds $((END - START)) --build-seconds $((BUILD_END - START)) \
  --load "$LOAD_START / $(cut -d' ' -f1-3 /proc/loadavg)"
echo "wrote $OUT/paper_table.md and $OUT/paper_fig*.png in $((END - START)) s"
