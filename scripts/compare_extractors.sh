#!/usr/bin/env bash
# Runs the detector's accuracy test sets twice, with cv::SIFT (REFGRASP_SIFT=opencv) and with the
# project's fast SIFT (the default), and prints their tables side by side: pose accuracy (48
# poses), jitter, stereo, hard cases (found per category), false positives (500 clutter frames),
# the real-photo box. Needs a build: cmake -S . -B build && cmake --build build -j2.
# Usage: scripts/compare_extractors.sh [build dir (default build)] [output dir (default out/compare_extractors)]
set -euo pipefail
build=${1:-build}
out=${2:-out/compare_extractors}
mkdir -p "$out"
filter='Detector.*:HardCases.*:FalsePositives.*:SiftFast.DetectorFinds*'
for impl in opencv fast; do
  echo "== $impl: $build/tests/test_detector --gtest_filter=$filter" >&2
  REFGRASP_SIFT=$impl "$build/tests/test_detector" --gtest_filter="$filter" > "$out/$impl.txt" 2>&1 || true
done
for impl in opencv fast; do
  echo "=================== $impl ==================="
  grep -E '^\| (paper|refined|detect\(\))|^Jitter|jitter|std|^(small|motion|repeated|symmetric|3 instances|overall)|False positives|cookie box|OK \]|FAILED' "$out/$impl.txt" || true
done
