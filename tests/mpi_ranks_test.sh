#!/usr/bin/env bash
# Distributed runs (mpirun -np N vdb_isosimp): the same bytes as one process for 1, 2 and 4 ranks and
# 1 and 2 threads, on a generated volume cut into many slabs (the noise volume is a fog grid: its default
# iso-value comes from every rank's part of the leaves); a rank that fails (a damaged leaf record, damaged
# voxels, a different file on one rank, a killed rank) ends the run non-zero with one line of ours and no
# output file.
# Usage: mpi_ranks_test.sh BUILD_DIR
set -euo pipefail
B=$1
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
fail() { echo "FAIL: $*"; exit 1; }

"$B/make_volume" noise -n 112 -o "$W/v.vdb" > /dev/null
"$B/make_volume" ct-int -n 96 --rotated -o "$W/ct.vdb" > /dev/null
for V in v ct; do
  # About 50 and 35 slabs: enough for every rank to hold several and for the tree to be a few levels
  # deep; a batch of 1000 faces makes every slab and every join decimate (the merges carry queues).
  # The noise volume runs with a face target: each rank counts its own blocks' faces.
  ARGS=(--batch 1000 --slab-blocks 64 -q)
  if [ $V = v ]; then ARGS+=(--faces 10000); else ARGS+=(--ratio 0.05); fi
  "$B/vdb_isosimp" "$W/$V.vdb" "${ARGS[@]}" -o "$W/${V}_one.ply" --report "$W/${V}_one.json"
  slabs=$(sed -n 's/.*"slabs": *\([0-9]*\).*/\1/p' "$W/${V}_one.json")
  decimations=$(sed -n 's/.*"decimations": *\([0-9]*\).*/\1/p' "$W/${V}_one.json")
  [ "$slabs" -ge 8 ] || fail "$V: only $slabs slabs"
  [ "$decimations" -ge $((2 * slabs)) ] || fail "$V: only $decimations decimations for $slabs slabs"
  full=$(sed -n 's/.*"faces_full": *\([0-9]*\).*/\1/p' "$W/${V}_one.json")
  for N in 1 2 4; do
    for T in 1 2; do
      mpirun -np $N "$B/vdb_isosimp" "$W/$V.vdb" "${ARGS[@]}" --threads $T -o "$W/${V}_$N.ply" --report "$W/${V}_$N.json"
      cmp "$W/${V}_one.ply" "$W/${V}_$N.ply" || fail "$V: $N ranks x $T threads wrote other bytes"
      ranks=$(sed -n 's/.*"ranks": *\([0-9]*\).*/\1/p' "$W/${V}_$N.json")
      [ "$ranks" = "$N" ] || fail "$V: report says $ranks ranks, not $N"
      grep -q "\"faces_full\": $full," "$W/${V}_$N.json" || fail "$V: $N ranks counted other than $full faces"
      for k in queue_pops queue_dead queue_stale collapse_attempts collapses; do
        [ "$(grep -o "\"$k\": [0-9]*" "$W/${V}_$N.json")" = "$(grep -o "\"$k\": [0-9]*" "$W/${V}_one.json")" ] ||
          fail "$V: $N ranks x $T threads report other $k than one process"
      done
      grep -q "\"rank_seconds\": \[[0-9]" "$W/${V}_$N.json" || fail "$V: no per-rank seconds"
      echo "$V: $N ranks x $T threads: same bytes as one process ($slabs slabs, $decimations decimations)"
    done
  done
done

# What vertices carry beyond position and quadric travels with the pieces: the drift under an error
# bound, the attribute quadric with an attribute weight; a LOD chain starts from the same root.
for EXTRA in "--max-error 0.3" "--attributes noise --attribute-weight 2 --ratio 0.05" "--lods 0.2,0.05"; do
  # shellcheck disable=SC2086
  "$B/vdb_isosimp" "$W/v.vdb" $EXTRA --batch 1000 --slab-blocks 64 -q -o "$W/x_one.ply"
  # shellcheck disable=SC2086
  mpirun -np 2 "$B/vdb_isosimp" "$W/v.vdb" $EXTRA --batch 1000 --slab-blocks 64 -q -o "$W/x_two.ply"
  for f in x_one.ply x_one_lod0.ply x_one_lod1.ply; do
    [ -f "$W/$f" ] || continue
    cmp "$W/$f" "$W/${f/one/two}" || fail "$EXTRA: 2 ranks wrote other bytes ($f)"
  done
  echo "$EXTRA: 2 ranks, same bytes as one process"
done

# Retired interiors travel with the pieces: forced low, every join of two nodes above 2000 faces
# writes its interior out, on whichever rank it runs.
"$B/vdb_isosimp" "$W/v.vdb" --retire-above 2000 --ratio 0.05 --batch 1000 --slab-blocks 64 -q -o "$W/t_one.ply" --report "$W/t_one.json"
retired=$(sed -n 's/.*"faces_retired": *\([0-9]*\).*/\1/p' "$W/t_one.json")
[ "$retired" -gt 0 ] || fail "--retire-above 2000: no face retired"
for N in 2 4; do
  mpirun -np $N "$B/vdb_isosimp" "$W/v.vdb" --retire-above 2000 --ratio 0.05 --batch 1000 --slab-blocks 64 --threads 1 -q -o "$W/t_$N.ply"
  cmp "$W/t_one.ply" "$W/t_$N.ply" || fail "--retire-above 2000: $N ranks wrote other bytes"
done
echo "--retire-above 2000: $retired faces retired; 2 and 4 ranks, same bytes as one process"

# A face target on a large volume counts a sample of the blocks (a gyroid of 128 slabs of 38 blocks, a
# run each: every fourth run), each rank its own sampled runs; a sample too coarse to say anything (the
# noise volume, every fifth run) is followed by a count of every block, agreed among the ranks again.
"$B/make_volume" gyroid -n 128 -o "$W/g.vdb" > /dev/null
for CASE in "g 32 4" "v 8 1"; do
  read -r V S STRIDE <<< "$CASE"
  ARGS=(--faces 20000 --count-sample "$S" --batch 1000 --slab-blocks 64 -q)
  "$B/vdb_isosimp" "$W/$V.vdb" "${ARGS[@]}" -o "$W/s_one.ply" --report "$W/s_one.json"
  grep -q "\"count_stride\": $STRIDE," "$W/s_one.json" || fail "$V: count stride is not $STRIDE"
  for N in 2 4; do
    mpirun -np $N "$B/vdb_isosimp" "$W/$V.vdb" "${ARGS[@]}" --threads 1 -o "$W/s_$N.ply" --report "$W/s_$N.json"
    cmp "$W/s_one.ply" "$W/s_$N.ply" || fail "$V --count-sample $S: $N ranks wrote other bytes"
    grep -q "\"count_stride\": $STRIDE," "$W/s_$N.json" || fail "$V: $N ranks counted at another stride"
  done
  echo "$V --count-sample $S (stride $STRIDE): 2 and 4 ranks, same bytes as one process"
done

# A chain with the default batch and larger slabs: its coarser level's slab copies are decimated region by
# region (more than one region's share of faces to remove each), on 2 ranks as in one process.
"$B/vdb_isosimp" "$W/v.vdb" --lods 0.2,0.05 --slab-blocks 512 -q -o "$W/r_one.ply"
mpirun -np 2 "$B/vdb_isosimp" "$W/v.vdb" --lods 0.2,0.05 --slab-blocks 512 --threads 1 -q -o "$W/r_two.ply"
for f in r_one_lod0.ply r_one_lod1.ply; do cmp "$W/$f" "$W/${f/one/two}" || fail "chain, larger slabs: 2 ranks wrote other bytes ($f)"; done
echo "--lods 0.2,0.05 --slab-blocks 512: 2 ranks, same bytes as one process"

# Many ranks on a deep tree: 183 slabs on 24 ranks, each rank's share a node 4-5 levels down, every level
# of a chain sent up and joined across ranks.
"$B/make_volume" noise -n 64 -o "$W/small.vdb" > /dev/null
"$B/vdb_isosimp" "$W/small.vdb" --lods 0.2,0.05 --batch 1000 --slab-blocks 4 -q -o "$W/d_one.ply"
mpirun -np 24 "$B/vdb_isosimp" "$W/small.vdb" --lods 0.2,0.05 --batch 1000 --slab-blocks 4 --threads 1 -q -o "$W/d_many.ply"
for f in d_one_lod0.ply d_one_lod1.ply; do cmp "$W/$f" "$W/${f/one/many}" || fail "chain, deep tree: 24 ranks wrote other bytes ($f)"; done
echo "--lods 0.2,0.05 --slab-blocks 4 (183 slabs): 24 ranks, same bytes as one process"

# A fog grid of tiles beside voxels: the blocks along the tiles' faces divide among the ranks with the
# leaves (each lists its share, the ranks merge the shares), for 3 ranks as in one process.
/usr/bin/python3 - "$W/tiles.vdb" << 'EOF'
import sys
import pyopenvdb as vdb
g = vdb.FloatGrid(0.0)
g.name = "density"
g.fill((0, 0, 0), (255, 127, 127), 1.0, True)  # two 128^3 tiles
acc = g.getAccessor()
for z in range(40):
    for y in range(40):
        for x in range(256, 300):
            acc.setValueOn((x, y, z), ((x * 7 + y * 13 + z * 29) % 31) / 31.0)
vdb.write(sys.argv[1], grids=[g])
EOF
"$B/vdb_isosimp" "$W/tiles.vdb" --iso 0.5 --ratio 0.2 --batch 1000 --slab-blocks 64 -q -o "$W/tiles_one.ply" --report "$W/tiles_one.json"
tslabs=$(sed -n 's/.*"slabs": *\([0-9]*\).*/\1/p' "$W/tiles_one.json")
[ "$tslabs" -ge 6 ] || fail "tiles: only $tslabs slabs"
mpirun -np 3 "$B/vdb_isosimp" "$W/tiles.vdb" --iso 0.5 --ratio 0.2 --batch 1000 --slab-blocks 64 --threads 1 -q -o "$W/tiles_3.ply"
cmp "$W/tiles_one.ply" "$W/tiles_3.ply" || fail "tiles: 3 ranks wrote other bytes"
echo "tiles beside voxels ($tslabs slabs): 3 ranks, same bytes as one process"

# Each rank reads the topology of its share of the lower internal nodes as it opens the file, and
# those its slabs sample once it knows them: a fog box of tiles alone (no leaf, so no node weighs
# leaves) and a level set with tiles inside, both over several lower nodes, on 3 and 8 ranks.
"$B/make_volume" fog-box -n 200 --rotated -o "$W/fb.vdb" > /dev/null
"$B/make_volume" sphere -n 200 -o "$W/sph.vdb" > /dev/null
for V in fb sph; do
  "$B/vdb_isosimp" "$W/$V.vdb" --ratio 0.05 --slab-blocks 32 -q -o "$W/${V}_one.ply"
  for N in 3 8; do
    mpirun -np $N "$B/vdb_isosimp" "$W/$V.vdb" --ratio 0.05 --slab-blocks 32 --threads 1 -q -o "$W/${V}_$N.ply"
    cmp "$W/${V}_one.ply" "$W/${V}_$N.ply" || fail "$V: $N ranks wrote other bytes"
  done
  echo "$V, its lower nodes divided among ranks: 3 and 8 ranks, same bytes as one process"
done
# One slab: rank 0 holds every block and reads every node they sample, the others none.
"$B/vdb_isosimp" "$W/sph.vdb" --ratio 0.05 --slab-blocks 100000 -q -o "$W/one_slab.ply"
mpirun -np 3 "$B/vdb_isosimp" "$W/sph.vdb" --ratio 0.05 --slab-blocks 100000 --threads 1 -q -o "$W/one_slab_3.ply"
cmp "$W/one_slab.ply" "$W/one_slab_3.ply" || fail "one slab: 3 ranks wrote other bytes"
echo "one slab on 3 ranks: same bytes as one process"

# Damaged leaf records (at a quarter and at 60 % of the file; the leaf at z = 96 of 112 only the last
# rank reads): every rank walks the records before OpenVDB reads the tree, and the run ends with the
# line one process prints.
for pct in 25 60; do
  cp "$W/v.vdb" "$W/bad.vdb"
  size=$(stat -c %s "$W/bad.vdb")
  head -c 4000 /dev/zero | tr '\0' 'Z' | dd of="$W/bad.vdb" bs=1 seek=$((size * pct / 100)) conv=notrunc status=none
  set +e
  "$B/vdb_isosimp" "$W/bad.vdb" --ratio 0.05 --slab-blocks 64 -q -o "$W/bad.ply" 2> "$W/one.err"
  set -e
  one=$(grep '^vdb_isosimp: ' "$W/one.err")
  [ $pct != 60 ] || echo "$one" | grep -q "bad.vdb.*leaf \[64, 16, 96\]" || fail "damaged file: the line does not name the file and leaf"
  for N in 2 4; do
    set +e
    mpirun -np $N "$B/vdb_isosimp" "$W/bad.vdb" --ratio 0.05 --slab-blocks 64 -q -o "$W/bad.ply" 2> "$W/bad.err"
    code=$?
    set -e
    [ $code -ne 0 ] || fail "damaged file: exit 0"
    ours=$(grep -c '^vdb_isosimp: ' "$W/bad.err" || true)
    [ "$ours" = 1 ] || { cat "$W/bad.err"; fail "damaged file, $N ranks: $ours lines of ours, not 1"; }
    [ "$(grep '^vdb_isosimp: ' "$W/bad.err")" = "$one" ] || fail "damaged file at $pct %, $N ranks: not the line of one process ($one)"
    ls "$W"/bad.ply* > /dev/null 2>&1 && fail "damaged file: output left behind"
    echo "damaged file at $pct %, $N ranks: exit $code, one line: $(grep '^vdb_isosimp: ' "$W/bad.err")"
  done
done

# Damaged compressed voxels that the walk of the records cannot see (bytes scrambled inside one leaf's
# chunk: the last bytes where two files differ in that leaf's values), in a fog grid without --iso: each
# rank reads its part of the leaves for the default iso-value, and the one that meets the leaf ends the
# run with its message, the line of one process (and which rank).
/usr/bin/python3 - "$W" << 'EOF'
import sys
import pyopenvdb as vdb
d = sys.argv[1]
def grid(marked):
    g = vdb.FloatGrid(0.0)
    g.name = "density"
    acc = g.getAccessor()
    for z in range(48):
        for y in range(48):
            for x in range(48):
                v = ((x * 7 + y * 13 + z * 29) % 31) / 31.0
                if marked and 32 <= x < 40 and 32 <= y < 40 and 32 <= z < 40:
                    v = 1.0 - v * 0.5
                acc.setValueOn((x, y, z), v)
    return g
vdb.write(d + "/da.vdb", grids=[grid(False)])
vdb.write(d + "/db.vdb", grids=[grid(True)])
a, b = open(d + "/da.vdb", "rb").read(), open(d + "/db.vdb", "rb").read()
ea, eb = len(a), len(b)
while ea > 0 and eb > 0 and a[ea - 1] == b[eb - 1]:
    ea, eb = ea - 1, eb - 1
bad = bytearray(a)
for k in range(ea - 24, ea):
    bad[k] = (0xA5 ^ (k * 37)) & 0xFF
open(d + "/voxels.vdb", "wb").write(bad)
EOF
set +e
"$B/vdb_isosimp" "$W/voxels.vdb" -q -o "$W/voxels.ply" 2> "$W/one.err"
set -e
one=$(grep '^vdb_isosimp: ' "$W/one.err")
echo "$one" | grep -q "voxels.vdb: grid 'density', leaf \[32, 32, 32\]: compressed data is damaged" || fail "damaged voxels: not found by one process ($one)"
for N in 2 4; do
  set +e
  mpirun -np $N "$B/vdb_isosimp" "$W/voxels.vdb" -q --threads 1 -o "$W/voxels.ply" 2> "$W/voxels.err"
  code=$?
  set -e
  [ $code -ne 0 ] || fail "damaged voxels, $N ranks: exit 0"
  ours=$(grep -c '^vdb_isosimp: ' "$W/voxels.err" || true)
  [ "$ours" = 1 ] || { cat "$W/voxels.err"; fail "damaged voxels, $N ranks: $ours lines of ours, not 1"; }
  line=$(grep '^vdb_isosimp: ' "$W/voxels.err")
  [ "${line% (rank *)}" = "$one" ] || fail "damaged voxels, $N ranks: '$line' is not the line of one process"
  ls "$W"/voxels.ply* > /dev/null 2>&1 && fail "damaged voxels, $N ranks: output left behind"
  echo "damaged voxels, default iso, $N ranks: exit $code, one line: $line"
done

# A missing file on every rank: one line, not one per rank.
set +e
mpirun -np 4 "$B/vdb_isosimp" "$W/missing.vdb" -q -o "$W/missing.ply" 2> "$W/missing.err"
code=$?
set -e
[ $code -ne 0 ] || fail "missing file: exit 0"
ours=$(grep -c '^vdb_isosimp: ' "$W/missing.err" || true)
[ "$ours" = 1 ] || { cat "$W/missing.err"; fail "missing file: $ours lines of ours, not 1"; }
echo "missing file: exit $code, one line"

# Rank 1 reads another file (a copy that differs between machines: another noise seed, the same
# blocks): one line, nothing written. The same wrapper with the same file meshes as one process.
"$B/make_volume" noise -n 112 --seed 7 -o "$W/other.vdb" > /dev/null
cat > "$W/rank1_reads.sh" << 'EOF'
#!/usr/bin/env bash
# Rank 1 reads $OTHER in place of the first argument.
if [ "$OMPI_COMM_WORLD_RANK" = 1 ]; then f=$OTHER; else f=$1; fi
shift
exec "$EXE" "$f" "$@"
EOF
chmod +x "$W/rank1_reads.sh"
for OTHER in "$W/other.vdb" "$W/v.vdb"; do
  rm -f "$W/mixed.ply"
  set +e
  mpirun -np 2 -x OTHER="$OTHER" -x EXE="$B/vdb_isosimp" "$W/rank1_reads.sh" "$W/v.vdb" --ratio 0.05 --slab-blocks 64 -q \
    -o "$W/mixed.ply" 2> "$W/mixed.err"
  code=$?
  set -e
  if [ "$OTHER" = "$W/v.vdb" ]; then
    [ $code = 0 ] || { cat "$W/mixed.err"; fail "the same file through the wrapper: exit $code"; }
    continue
  fi
  [ $code -ne 0 ] || fail "a different file on rank 1: exit 0"
  ours=$(grep -c '^vdb_isosimp: ' "$W/mixed.err" || true)
  [ "$ours" = 1 ] || { cat "$W/mixed.err"; fail "a different file on rank 1: $ours lines of ours, not 1"; }
  grep -q "^vdb_isosimp: .*v.vdb: the ranks read different files" "$W/mixed.err" || { cat "$W/mixed.err"; fail "a different file on rank 1: not said"; }
  ls "$W"/mixed.ply* > /dev/null 2>&1 && fail "a different file on rank 1: output left behind"
  echo "a different file on rank 1: exit $code, one line"
done

# Rank 1's copy damaged in one leaf record (the same stored tree, so the same digest), at a quarter of
# the file (in rank 0's part of the shared walk) and at 60 % (in its own part): rank 1 walks every
# record it decompresses, so either it reads that leaf and the run ends with one line from rank 1 and
# nothing written, or it does not and the mesh is the undamaged file's, byte for byte.
"$B/vdb_isosimp" "$W/v.vdb" --ratio 0.05 --slab-blocks 64 -q -o "$W/good.ply"
for pct in 25 60; do
  cp "$W/v.vdb" "$W/bad1.vdb"
  size=$(stat -c %s "$W/bad1.vdb")
  head -c 4000 /dev/zero | tr '\0' 'Z' | dd of="$W/bad1.vdb" bs=1 seek=$((size * pct / 100)) conv=notrunc status=none
  rm -f "$W/one_bad.ply"
  set +e
  mpirun -np 2 -x OTHER="$W/bad1.vdb" -x EXE="$B/vdb_isosimp" "$W/rank1_reads.sh" "$W/v.vdb" --ratio 0.05 \
    --slab-blocks 64 -q -o "$W/one_bad.ply" 2> "$W/one_bad.err"
  code=$?
  set -e
  if [ $code = 0 ]; then
    cmp "$W/one_bad.ply" "$W/good.ply" || fail "rank 1's copy damaged at $pct %: exit 0 with another mesh"
    echo "rank 1's copy damaged at $pct %: the leaf is not rank 1's; the undamaged file's mesh"
  else
    ours=$(grep -c '^vdb_isosimp: ' "$W/one_bad.err" || true)
    [ "$ours" = 1 ] || { cat "$W/one_bad.err"; fail "rank 1's copy damaged at $pct %: $ours lines of ours, not 1"; }
    grep -q "^vdb_isosimp: .*bad1.vdb: grid '[a-z]*', leaf .*: compressed data is damaged .* (rank 1)$" "$W/one_bad.err" ||
      { cat "$W/one_bad.err"; fail "rank 1's copy damaged at $pct %: the line does not name rank 1's file and leaf"; }
    ls "$W"/one_bad.ply* > /dev/null 2>&1 && fail "rank 1's copy damaged at $pct %: output left behind"
    echo "rank 1's copy damaged at $pct %: exit $code, one line: $(grep '^vdb_isosimp: ' "$W/one_bad.err")"
  fi
done

# A killed rank: mpirun ends the others; nothing is written.
"$B/make_volume" noise -n 160 -o "$W/big.vdb" > /dev/null
mpirun -np 2 "$B/vdb_isosimp" "$W/big.vdb" --ratio 0.05 --slab-blocks 64 --threads 1 -q -o "$W/kill.ply" \
  > /dev/null 2> "$W/kill.err" &
run=$!
victim=""
for _ in $(seq 100); do
  victim=$(pgrep -f "^$B/vdb_isosimp $W/big.vdb" | sort -n | tail -1 || true)
  [ -n "$victim" ] && [ "$(pgrep -f "^$B/vdb_isosimp $W/big.vdb" | wc -l)" -ge 2 ] && break
  sleep 0.1
done
sleep 0.5
kill -9 "$victim"
set +e
wait $run
code=$?
set -e
[ $code -ne 0 ] || fail "killed rank: exit 0"
ls "$W"/kill.ply* > /dev/null 2>&1 && fail "killed rank: output left behind"
echo "killed rank: exit $code, no output"
echo "PASS"
