#!/usr/bin/env bash
# Fuzzes the model loader (InrModel::loadBytes) with libFuzzer + ASan + UBSan for a fixed number of
# executions; exits non-zero on any finding (crash, sanitizer report, hang, invariant violation).
#
#   Tools/run-fuzz.sh [EXECUTIONS] [libFuzzer options...]     (default 200000, about half a minute)
#   nice -n 10 Tools/run-fuzz.sh 10000000                     (a long run; see Docs/testing.md)
#
# Builds with clang into ${INR_FUZZ_BUILD_DIR:-build-fuzz} (INR_FUZZ=ON: the loader and the fuzzer
# only). Seeds: Testing/Data/malformed and Testing/Data/models/*.inr; the corpus it grows is kept in
# the build folder (corpus/), findings are written there as crash-*/timeout-*/oom-* and reproduced
# by running the fuzzer on the file: build-fuzz/Testing/Fuzz/inr_model_fuzzer FILE
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-200000}
shift || true
BUILD_DIR=${INR_FUZZ_BUILD_DIR:-build-fuzz}
CXX_CLANG=${INR_FUZZ_CXX:-$(command -v clang++ || true)}
if [ -z "$CXX_CLANG" ]; then
  echo "run-fuzz: clang++ not found (apt-get install clang libclang-rt-dev; Tools/install-deps.sh)" >&2
  exit 1
fi
CC_CLANG=${INR_FUZZ_CC:-${CXX_CLANG%++}}
if [ ! -f "$BUILD_DIR/build.ninja" ]; then
  cmake -S . -B "$BUILD_DIR" -G Ninja -DINR_FUZZ=ON -DINR_BUILD_TESTS=OFF -DINR_ENABLE_CUDA=OFF \
    -DINR_ENABLE_PARAVIEW=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_COMPILER="$CXX_CLANG" -DCMAKE_C_COMPILER="$CC_CLANG" >/dev/null
fi
cmake --build "$BUILD_DIR" --target inr_model_fuzzer -j "${INR_FUZZ_JOBS:-$(nproc)}"

# Seeds: the malformed corpus and the small shipped models (the READMEs and reference tables are
# not model files).
SEEDS="$BUILD_DIR/seeds"
CORPUS="$BUILD_DIR/corpus"
ARTIFACTS="$BUILD_DIR/findings"
rm -rf "$SEEDS"
mkdir -p "$SEEDS" "$CORPUS" "$ARTIFACTS"
cp Testing/Data/malformed/*.inr Testing/Data/models/*.inr "$SEEDS/"
rm -f "$ARTIFACTS"/crash-* "$ARTIFACTS"/timeout-* "$ARTIFACTS"/oom-* "$ARTIFACTS"/leak-*

export ASAN_OPTIONS=${ASAN_OPTIONS:-halt_on_error=1:detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
start=$(date +%s)
set +e
"$BUILD_DIR/Testing/Fuzz/inr_model_fuzzer" -runs="$RUNS" -dict=Testing/Fuzz/inr_model.dict \
  -max_len=65536 -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
  -artifact_prefix="$ARTIFACTS/" "$@" "$CORPUS" "$SEEDS" 2>"$BUILD_DIR/fuzz.log"
rc=$?
set -e
grep -E "^(#[0-9]+ +DONE|stat::number_of_executed_units|stat::average_exec_per_sec|Done )" "$BUILD_DIR/fuzz.log" || true
findings=$(find "$ARTIFACTS" -type f | wc -l)
echo "run-fuzz: $RUNS executions requested, exit status $rc, $findings finding(s), $(( $(date +%s) - start )) s" \
     "(log: $BUILD_DIR/fuzz.log)"
if [ "$rc" -ne 0 ] || [ "$findings" -ne 0 ]; then
  tail -n 60 "$BUILD_DIR/fuzz.log" >&2
  ls "$ARTIFACTS" >&2
  exit 1
fi
