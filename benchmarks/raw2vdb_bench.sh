#!/usr/bin/env bash
# raw2vdb memory and throughput benchmark (issue 3, acceptance 3).
#
# Generates a deterministic CT-like N^3 u8 raw volume (default 1024^3 = 1 GiB): air (0) around an
# ellipsoidal body of constant soft tissue (60), a bone shell with a density ramp, a smooth-gradient
# "organ" and a noisy "lung". Then converts it with /usr/bin/time -v and prints the input rate (MB/s,
# 10^6 bytes of input per second of wall time, header to renamed .vdb) and the peak RSS, checked
# against the targets: peak RSS < 1 GiB and >= 100 MB/s.
#
# Usage: benchmarks/raw2vdb_bench.sh [N]      (env: BUILD=build, WORK=$BUILD/raw2vdb_bench, KEEP=1
#                                              keeps the generated files for the next run)
# Note: the input was just written, so it is read from the page cache (warm); the rate then measures
# the converter, not the disk.
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-1024}
BUILD=${BUILD:-build}
WORK=${WORK:-$BUILD/raw2vdb_bench}
EXE=$BUILD/raw2vdb
[ -x "$EXE" ] || { echo "raw2vdb_bench: $EXE not found (build it: cmake --build $BUILD --target raw2vdb)" >&2; exit 1; }
[ -x /usr/bin/time ] || { echo "raw2vdb_bench: /usr/bin/time missing (apt-get install time)" >&2; exit 1; }
mkdir -p "$WORK"

GEN=$WORK/gen_ct_u8
if [ ! -x "$GEN" ] || [ "$0" -nt "$GEN" ]; then
  cat > "$WORK/gen_ct_u8.cpp" <<'EOF'
// Writes an N^3 u8 CT-like phantom to stdout, z slice by z slice (x fastest).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>
int main(int argc, char** argv) {
    const int n = argc > 1 ? std::atoi(argv[1]) : 1024;
    std::vector<uint8_t> slice(size_t(n) * n);
    const double c = (n - 1) / 2.0;
    for (int z = 0; z < n; ++z) {
        const double w = (z - c) / (0.46 * n);
        for (int y = 0; y < n; ++y) {
            const double v = (y - c) / (0.36 * n);
            uint8_t* row = &slice[size_t(y) * n];
            for (int x = 0; x < n; ++x) {
                const double u = (x - c) / (0.42 * n);
                const double r = std::sqrt(u * u + v * v + w * w);          // body: r <= 1
                uint8_t val = 0;                                           // air
                if (r <= 1.0) {
                    val = 60;                                              // soft tissue
                    if (r > 0.62 && r < 0.70) val = uint8_t(170 + 600 * (r - 0.62));  // bone shell ramp
                    const double ox = (x - 0.38 * n) / (0.12 * n), oy = (y - 0.55 * n) / (0.12 * n), oz = (z - c) / (0.15 * n);
                    const double ro = ox * ox + oy * oy + oz * oz;
                    if (ro < 1.0) val = uint8_t(80 + 40 * (1.0 - ro));     // organ, smooth gradient
                    const double lx = (x - 0.62 * n) / (0.10 * n), ly = (y - 0.45 * n) / (0.13 * n), lz = (z - c) / (0.22 * n);
                    if (lx * lx + ly * ly + lz * lz < 1.0) {                // lung: low, noisy
                        uint32_t h = uint32_t(x) * 73856093u ^ uint32_t(y) * 19349663u ^ uint32_t(z) * 83492791u;
                        h ^= h >> 13; h *= 0x5bd1e995u; h ^= h >> 15;
                        val = uint8_t(5 + (h & 15));
                    }
                }
                row[x] = val;
            }
        }
        if (std::fwrite(slice.data(), 1, slice.size(), stdout) != slice.size()) return 1;
    }
    return std::fflush(stdout) == 0 ? 0 : 1;
}
EOF
  c++ -O2 -std=c++17 -o "$GEN" "$WORK/gen_ct_u8.cpp"
fi

RAW=$WORK/ct_${N}_u8.raw
BYTES=$((N * N * N))
if [ ! -f "$RAW" ] || [ "$(stat -c %s "$RAW")" -ne "$BYTES" ]; then
  echo "generating $RAW ($BYTES bytes)..."
  "$GEN" "$N" > "$RAW"
fi

OUT=$WORK/ct_${N}_u8.vdb
TIMES=$WORK/time.txt
CMD=("$EXE" "$RAW" -o "$OUT" --dims "$N,$N,$N" --type u8)
echo "command: /usr/bin/time -v ${CMD[*]}"
/usr/bin/time -v "${CMD[@]}" 2> "$TIMES" || { cat "$TIMES" >&2; exit 1; }

wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$TIMES")
seconds=$(echo "$wall" | awk -F: '{ if (NF == 3) print $1 * 3600 + $2 * 60 + $3; else print $1 * 60 + $2 }')
rss_kb=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$TIMES")
cpu=$(awk -F': ' '/Percent of CPU/ {print $2}' "$TIMES")
status=0
awk -v b="$BYTES" -v s="$seconds" -v k="$rss_kb" -v cpu="$cpu" -v vdb="$(stat -c %s "$OUT")" 'BEGIN {
  rate = b / 1e6 / s; mib = k / 1024;
  printf "input: %.0f MB   wall: %.2f s   rate: %.1f MB/s   peak RSS: %.1f MiB   CPU: %s   output: %.1f MB\n", b / 1e6, s, rate, mib, cpu, vdb / 1e6;
  ok_rss = (k * 1024 < 1073741824); ok_rate = (rate >= 100);
  printf "peak RSS < 1 GiB: %s   rate >= 100 MB/s: %s\n", ok_rss ? "PASS" : "FAIL", ok_rate ? "PASS" : "FAIL";
  exit !(ok_rss && ok_rate) }' || status=$?
if [ "${KEEP:-0}" != 1 ]; then rm -f "$RAW" "$OUT"; fi
exit $status
