#!/usr/bin/env bash
# Installs the build into a scratch prefix with `cmake --install`, then configures, builds and runs
# examples/consumer against the installed package only (find_package(vdb_isosimp CONFIG)).
# Usage: install_consumer_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1 src=$2
work=$(mktemp -d "${TMPDIR:-/tmp}/vdb_isosimp_install.XXXXXX")
trap 'rm -rf "$work"' EXIT

cmake --install "$build" --prefix "$work/prefix" > "$work/install.log" || { cat "$work/install.log"; exit 1; }
for f in include/vdb_isosimp/vdb_isosimp.h lib/cmake/vdb_isosimp/vdb_isosimpConfig.cmake \
         bin/vdb_isosimp bin/raw2vdb bin/mesh_stats bin/mesh_error; do
  [ -e "$work/prefix/$f" ] || { echo "not installed: $f"; exit 1; }
done
# The consumer sees the installed prefix only: not the source tree, not the build tree.
cmake -S "$src/examples/consumer" -B "$work/consumer" -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$work/prefix" > "$work/configure.log" 2>&1 || { cat "$work/configure.log"; exit 1; }
if grep -rq -- "$src/src\|$src/include\|$build" "$work/consumer/CMakeFiles/simplify_sphere.dir/flags.make"; then
  echo "consumer compiles against the source or build tree:"; cat "$work/consumer/CMakeFiles/simplify_sphere.dir/flags.make"; exit 1
fi
cmake --build "$work/consumer" -j2 > "$work/build.log" 2>&1 || { cat "$work/build.log"; exit 1; }

out=$("$work/consumer/simplify_sphere" "$work/sphere.glb" 2>/dev/null)
echo "$out"
[[ "$out" =~ ^sphere:\ ([0-9]+)\ -\>\ ([0-9]+)\ faces ]] || { echo "unexpected output"; exit 1; }
full=${BASH_REMATCH[1]} kept=${BASH_REMATCH[2]}
[ "$kept" -gt 1000 ] && [ "$kept" -le $(( full / 10 + 1 )) ] || { echo "bad face counts: $full -> $kept"; exit 1; }
[ "$(head -c 4 "$work/sphere.glb")" = "glTF" ] || { echo "no glTF file written"; exit 1; }

# The installed program gives the same face count for the same grid, through a file.
"$work/prefix/bin/vdb_isosimp" -q "$src/examples/data/torus_levelset.vdb" -r 0.1 --report "$work/p.json" -o "$work/p.ply"
out2=$("$work/consumer/simplify_sphere" "$work/c.ply" "$src/examples/data/torus_levelset.vdb" 2>/dev/null)
echo "$out2"
faces=$(sed -n 's/.*"faces_out": \([0-9]*\).*/\1/p' "$work/p.json")
[[ "$out2" == *" -> $faces faces"* ]] || { echo "consumer and program disagree: $faces faces vs '$out2'"; exit 1; }
# The installed Python module, if this build has one, imports from the prefix alone and agrees.
for dir in "$work"/prefix/lib/python3*/dist-packages; do
  [ -d "$dir" ] || continue
  out3=$(PYTHONPATH="$dir" /usr/bin/python3 -c "
import vdb_isosimp, sys
assert vdb_isosimp.__file__.startswith('$work/prefix/'), vdb_isosimp.__file__
v, f, r = vdb_isosimp.simplify(sys.argv[1], ratio=0.1)
print(len(f))" "$src/examples/data/torus_levelset.vdb")
  [ "$out3" = "$faces" ] || { echo "installed Python module: $out3 faces, program: $faces"; exit 1; }
  echo "installed Python module in $dir: $out3 faces"
done
# Every installed program runs from the prefix (its library found through its RPATH).
for p in vdb_isosimp raw2vdb mesh_stats mesh_error; do
  "$work/prefix/bin/$p" --help > /dev/null || { echo "installed $p does not run"; exit 1; }
done
echo "install consumer test passed"
