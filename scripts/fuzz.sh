#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz/ with clang (-fsanitize=fuzzer,address,undefined) into
# build-fuzz/ and runs each for a bounded time over the committed corpus (tests/fuzz/corpus/<target>):
# about 160 s of fuzzing in all. Fails on any crash, hang (>10 s on one input), leak or sanitizer report;
# the input that triggered it is kept as build-fuzz/artifacts/<target>-crash-*.
#   FUZZ_SECONDS=N      seconds per target (default: 20; raw2vdb and vdb_read get 1.5x)
#   --update-corpus     merge what the run found into tests/fuzz/corpus (minimised), to commit
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER=${FUZZ_SECONDS:-20}
UPDATE=0
[ "${1:-}" = "--update-corpus" ] && UPDATE=1
if ! command -v clang++ > /dev/null || ! ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a > /dev/null 2>&1; then
  ./scripts/deps.sh
fi
CXX=${FUZZ_CXX:-clang++}
OUT=build-fuzz
mkdir -p "$OUT/artifacts"
FLAGS=(-std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer -Isrc -Iinclude -Iconvert -Iapps -Itests/fuzz)
build() {  # target, sources and libraries...
  local t=$1; shift
  if [ ! -x "$OUT/$t" ] || [ -n "$(find tests/fuzz src include convert apps -newer "$OUT/$t" -name '*.[ch]*' | head -1)" ]; then
    echo "fuzz: building $t"
    "$CXX" "${FLAGS[@]}" "tests/fuzz/$t.cpp" "$@" -o "$OUT/$t"
  fi
}
build fuzz_nrrd convert/raw_header.cpp -lz
build fuzz_metaimage convert/raw_header.cpp -lz
build fuzz_nifti convert/raw_header.cpp -lz
build fuzz_cli_numbers convert/raw_header.cpp -lz
# OpenVDB headers use Imath half floats inline.
IMATH=$(pkg-config --libs Imath 2>/dev/null || echo -lImath-3_1)
# The converter reads image stacks too: DICOM through DCMTK, TIFF through libtiff.
STACKS=(convert/slice_source.cpp convert/dicom_series.cpp convert/tiff_stack.cpp)
STACK_LIBS=(-ldcmjpls -ldcmjpeg -ldcmimgle -ldcmdata -loflog -lofstd -ltiff)
build fuzz_raw2vdb convert/raw_header.cpp convert/raw_converter.cpp "${STACKS[@]}" -lopenvdb -ltbb $IMATH "${STACK_LIBS[@]}" -lz -lpthread
build fuzz_image_stacks convert/raw_header.cpp convert/raw_converter.cpp "${STACKS[@]}" -lopenvdb -ltbb $IMATH "${STACK_LIBS[@]}" -lz -lpthread
build fuzz_vdb_read src/vdb/volume_reader.cpp src/vdb/input_checks.cpp src/vdb/block_order.cpp src/core/marching_cubes.cpp \
  src/pipeline/memory_budget.cpp -lopenvdb -ltbb $IMATH -lz -lpthread
TARGETS=(fuzz_nrrd fuzz_metaimage fuzz_nifti fuzz_cli_numbers fuzz_raw2vdb fuzz_image_stacks fuzz_vdb_read)

# OpenVDB and TBB are not instrumented (see scripts/test_sanitize.sh for container-overflow).
export ASAN_OPTIONS="detect_container_overflow=0:detect_leaks=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
status=0
for t in "${TARGETS[@]}"; do
  secs=$SECONDS_PER
  maxlen=4096
  [ "$t" = fuzz_raw2vdb ] && secs=$((SECONDS_PER * 3 / 2))
  # .vdb inputs: the corpus files whole (up to 180 KB: no compression), so mutations reach their leaf data.
  [ "$t" = fuzz_vdb_read ] && secs=$((SECONDS_PER * 3 / 2)) && maxlen=196608
  corpus=tests/fuzz/corpus/${t#fuzz_}
  scratch=$OUT/new/${t#fuzz_}
  mkdir -p "$corpus" "$scratch"
  echo "fuzz: $t for ${secs}s over $(ls "$corpus" | wc -l) corpus inputs"
  if ! "$OUT/$t" "$scratch" "$corpus" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -max_len="$maxlen" \
       -print_final_stats=1 -artifact_prefix="$OUT/artifacts/$t-" > "$OUT/$t.log" 2>&1; then
    echo "fuzz: $t FAILED (log: $OUT/$t.log; input: $(ls -t "$OUT"/artifacts/"$t"-* 2>/dev/null | head -1))"
    tail -40 "$OUT/$t.log"
    status=1
  else
    grep -E "stat::number_of_executed_units|stat::new_units_added" "$OUT/$t.log" | tr '\n' ' ' | sed "s/^/fuzz: $t ok: /"; echo
  fi
  if [ "$UPDATE" = 1 ]; then
    "$OUT/$t" -merge=1 "$corpus" "$scratch" -max_len="$maxlen" > /dev/null 2>&1 || true
  fi
done
[ $status -eq 0 ] && echo "fuzz: ${#TARGETS[@]} passed, 0 failed" || echo "fuzz: some targets failed"
exit $status
