#!/usr/bin/env bash
# Builds the whole suite with AddressSanitizer + UndefinedBehaviorSanitizer (+ float-cast-overflow,
# which GCC's "undefined" group leaves out) in its own folder build-asan/ and runs every test:
#
#   bash scripts/sanitize.sh [CTEST_ARGS ...]        (e.g. -R 'Hostile|Scenario')
#   bash scripts/sanitize.sh --core                  only refgrasp_core and test_core (what CI runs:
#                                                    the shared readers: YAML, camera files, images)
#
# Any sanitizer report aborts the test that triggered it (-fno-sanitize-recover), so a clean run
# is a clean ctest. Slow: the sanitized build takes several times the normal one on 2 cores and
# the tests run 2-5x slower; the whole run is not part of scripts/test.sh (DEVELOPERS.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
JOBS=${JOBS:-2}
BUILD=${ASAN_BUILD_DIR:-build-asan}
SAN="-fsanitize=address,undefined,float-cast-overflow -fno-sanitize-recover=undefined,float-cast-overflow -fno-omit-frame-pointer"
core=0
if [ "${1:-}" = "--core" ]; then
  core=1
  shift
fi
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_FLAGS="$SAN" -DCMAKE_CXX_FLAGS="$SAN" -DCMAKE_EXE_LINKER_FLAGS="$SAN" \
  -DCMAKE_SHARED_LINKER_FLAGS="$SAN" -DREFGRASP_BUILD_BENCH=OFF > /dev/null
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
if [ $core -eq 1 ]; then
  cmake --build "$BUILD" -j "$JOBS" --target test_core
  "$BUILD/tests/test_core" --gtest_brief=1 "$@"
  exit
fi
cmake --build "$BUILD" -j "$JOBS"
cd "$BUILD"
ctest --output-on-failure -j "$JOBS" --timeout 1800 "$@"
