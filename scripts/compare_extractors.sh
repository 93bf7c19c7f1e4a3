#!/usr/bin/env bash
# Runs the detector's accuracy sets twice, with cv::SIFT (REFGRASP_SIFT=opencv) and with the
# project's fast SIFT (the default), and prints their tables one after the other: pose accuracy
# (48 poses), jitter, stereo, hard cases (found per category), false positives (500 clutter
# frames) from build/bench/bench_accuracy, and the real-photo box (its test's summary line).
# Needs a build: cmake -S . -B build && cmake --build build -j2.
# Usage: scripts/compare_extractors.sh [build dir (default build)] [output dir (default out/compare_extractors)]
set -euo pipefail
build=${1:-build}
out=${2:-out/compare_extractors}
mkdir -p "$out"
filter='SiftFast.DetectorFinds*'
for impl in opencv fast; do
  echo "== $impl: $build/bench/bench_accuracy; $build/tests/test_detector --gtest_filter=$filter" >&2
  REFGRASP_SIFT=$impl "$build/bench/bench_accuracy" > "$out/$impl.txt" 2>&1 || echo "bench_accuracy failed" >> "$out/$impl.txt"
  REFGRASP_SIFT=$impl "$build/tests/test_detector" --gtest_filter="$filter" > "$out/$impl.box.txt" 2>&1 || true
done
for impl in opencv fast; do
  echo "=================== $impl ==================="
  cat "$out/$impl.txt"
  grep -E 'cookie box|OK \]|FAILED' "$out/$impl.box.txt" || true
done
