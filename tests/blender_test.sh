#!/usr/bin/env bash
# Real-client test in Debian's Blender (background mode): the add-on in examples/blender/ imports a
# generated .vdb with the same vertex and face counts as vdb_isosimp reports for the same settings, and
# Blender's own importers read the program's PLY, OBJ, glTF binary and STL files with those counts.
# Usage: blender_test.sh BUILD_DIR SOURCE_DIR
# Without Blender: fails under CI (CI=true; scripts/deps.sh installs it), skips (exit 77) elsewhere.
set -euo pipefail
build=$1 src=$2
if ! command -v blender > /dev/null; then
  echo "blender is not installed (Debian: apt-get install blender; scripts/deps.sh installs it)"
  [ -n "${CI:-}" ] && exit 1
  exit 77
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/vdb_isosimp_blender.XXXXXX")
trap 'rm -rf "$work"' EXIT

# A CT-like fog volume with many components, and the program's meshes and report for its settings.
"$build/make_volume" noise -n 64 -o "$work/noise.vdb" > /dev/null
iso=0.2 ratio=0.15
# PLY and STL plain, OBJ and glTF with vertex normals (--normals).
for out in noise.ply noise.stl "noise.obj --normals" "noise.glb --normals"; do
  set -- $out
  "$build/vdb_isosimp" "$work/noise.vdb" -q --iso $iso --ratio $ratio -o "$work/$1" ${2:-} --report "$work/report.json"
done
verts=$(sed -n 's/.*"verts_out": \([0-9]*\).*/\1/p' "$work/report.json")
faces=$(sed -n 's/.*"faces_out": \([0-9]*\).*/\1/p' "$work/report.json")
echo "vdb_isosimp: $verts vertices, $faces faces (iso $iso, ratio $ratio)"
# A 3-frame sequence of copies, for the add-on's sequence import.
for f in 1 2 3; do cp "$work/noise.vdb" "$work/seq.000$f.vdb"; done

# Blender reads add-ons and preferences from these folders: keep the user's own untouched.
export BLENDER_USER_SCRIPTS="$work/scripts" BLENDER_USER_CONFIG="$work/config"
export VDB_ISOSIMP_PYTHONPATH="$build/python" VDB_ISOSIMP_EXE="$build/vdb_isosimp"
blender -b --factory-startup --python-exit-code 1 --python "$src/examples/blender/test_blender_import.py" -- \
  --addon "$src/examples/blender/io_import_vdb_isosimp.py" --vdb "$work/noise.vdb" --iso $iso --ratio $ratio \
  --verts "$verts" --faces "$faces" --sequence "$work/seq.0001.vdb" --sequence-frames 3 \
  --ply "$work/noise.ply" --obj "$work/noise.obj" --glb "$work/noise.glb" --stl "$work/noise.stl" 2>&1 |
  grep -v "^Read prefs\|^Warning: Unable to open\|^$" | tee "$work/blender.log"
status=${PIPESTATUS[0]}
[ "$status" -eq 0 ] || { echo "blender exited with $status"; exit 1; }
grep -q "^[0-9]* passed, 0 failed$" "$work/blender.log" || { echo "the Blender script did not finish"; exit 1; }
