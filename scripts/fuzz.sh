#!/usr/bin/env bash
# Fuzzes every configuration parser, the image decoding path and the recording and stamps readers
# (fuzz/targets.h) with libFuzzer, built by clang with AddressSanitizer + UndefinedBehaviorSanitizer
# in its own folder build-fuzz/:
#
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET ...]      (default: 60 s, every target)
#
# Each target starts from its seeds (the shipped config/ and media/targets/ files, fuzz/seeds/)
# and its corpus (build-fuzz/corpus/<target>/, kept between runs) and runs for the given time. Any
# finding (a crash, a sanitizer report, an exception other than the one-line refusals, an input
# taking > 10 s or > 2 GB) fails the script; its input is in build-fuzz/findings/<target>/. Fix it,
# then keep the input in fuzz/regressions/<target>/ (ctest replays it with the normal build).
# Not part of scripts/test.sh (too slow for CI): run it before touching a parser or a decoder.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${1:-60}
shift || true
ALL=(object camera_yaml camera_xml rig scenario robot_model detector_options image recording_index
     recording_json stamps)
[ $# -gt 0 ] && TARGETS=("$@") || TARGETS=("${ALL[@]}")
JOBS=${JOBS:-2}
BUILD=${FUZZ_BUILD_DIR:-build-fuzz}

# Debian's clang and its sanitizer/libFuzzer runtimes (plus the normal build dependencies).
bash scripts/install_deps.sh
missing=()
for p in clang libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
fi

SAN="-fsanitize=address,undefined,float-cast-overflow -fno-sanitize-recover=all -fno-omit-frame-pointer"
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_C_FLAGS="-fsanitize=fuzzer-no-link $SAN" -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link $SAN" \
  -DCMAKE_EXE_LINKER_FLAGS="$SAN" \
  -DREFGRASP_FUZZ=ON -DREFGRASP_BUILD_TESTS=OFF -DREFGRASP_BUILD_BENCH=OFF > "$BUILD.configure.log"
mv "$BUILD.configure.log" "$BUILD/configure.log"  # not left in the source tree
cmake --build "$BUILD" -j "$JOBS" --target $(printf 'fuzz_%s ' "${TARGETS[@]}")

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
failed=()
printf '%-18s %12s %10s %8s  %s\n' target executions exec/s corpus result
for t in "${TARGETS[@]}"; do
  corpus="$BUILD/corpus/$t" findings="$BUILD/findings/$t"
  mkdir -p "$corpus" "$findings"
  seeds=()
  case $t in
    object) seeds=(config/objects) ;;
    camera_yaml) seeds=(config/cameras config/objects) ;;
    camera_xml) seeds=(fuzz/seeds/camera_xml) ;;
    rig) seeds=(config/cameras) ;;
    scenario) seeds=(config/scenarios) ;;
    robot_model|detector_options) seeds=(config) ;;
    image) seeds=(fuzz/seeds/image media/targets) ;;
    recording_index|recording_json|stamps) seeds=("fuzz/seeds/$t") ;;
  esac
  [ -d "fuzz/regressions/$t" ] && seeds+=("fuzz/regressions/$t")
  log="$BUILD/fuzz_$t.log"
  set +e
  "$BUILD/fuzz/fuzz_$t" -max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/" "$corpus" "${seeds[@]}" > "$log" 2>&1
  rc=$?
  set -e
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  size=$(find "$corpus" -type f | wc -l)
  if [ $rc -eq 0 ]; then result=clean; else result="FINDING (exit $rc, $log, $findings)"; failed+=("$t"); fi
  printf '%-18s %12s %10s %8s  %s\n' "$t" "${execs:-0}" "${rate:-0}" "$size" "$result"
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in ${failed[*]}"
  exit 1
fi
echo "fuzz: ${#TARGETS[@]} targets clean, ${SECONDS_EACH} s each"
