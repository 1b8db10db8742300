#!/usr/bin/env bash
# raw2vdb on a large 16-bit TIFF stack (issue 18's benchmark): writes a 1 GiB ImageJ stack with
# make_tiff_stack (1024x1024x512 u16, an ellipsoid of signal over 0), converts it with raw2vdb under
# /usr/bin/time and prints the throughput (input bytes / wall time, the .vdb write included) and the
# peak resident memory, against the bars of >= 100 MB/s and < 1 GiB. The stack is read right after it
# was written, so from the page cache: this measures the converter, not the disk.
#   SIZE=W,H,D   stack size (default 1024,1024,512)
#   BUILD_DIR=…  build directory holding (or to build) raw2vdb and make_tiff_stack (default build)
#   KEEP=1       keep the scratch folder (default: removed)
set -euo pipefail
cd "$(dirname "$0")/.."
SIZE=${SIZE:-1024,1024,512}
BUILD=${BUILD_DIR:-build}
[ -f "$BUILD/CMakeCache.txt" ] || cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$BUILD" -j"$(nproc)" --target raw2vdb make_tiff_stack > /dev/null
work=$(mktemp -d "${TMPDIR:-/tmp}/bench_tiff_stack.XXXXXX")
[ "${KEEP:-0}" = 1 ] || trap 'rm -rf "$work"' EXIT
"$BUILD/make_tiff_stack" "$work/stack.tif" --size "$SIZE"
IFS=, read -r W H D <<< "$SIZE"
bytes=$((W * H * D * 2))
/usr/bin/time -f '%e %M' -o "$work/time.txt" "$BUILD/raw2vdb" "$work/stack.tif" -o "$work/stack.vdb"
read -r secs rss_kb < "$work/time.txt"
ls -l "$work/stack.vdb" | awk '{ printf "bench: output %.1f MiB\n", $5 / 1048576 }'
awk -v b="$bytes" -v s="$secs" -v r="$rss_kb" 'BEGIN {
  mbs = b / 1e6 / s; mib = r / 1024;
  printf "bench: %.0f MB in %.2f s = %.0f MB/s (bar >= 100), peak RSS %.0f MiB (bar < 1024)\n", b / 1e6, s, mbs, mib;
  exit !(mbs >= 100 && mib < 1024) }' && echo "bench: both bars held" || { echo "bench: a bar was missed"; exit 1; }
