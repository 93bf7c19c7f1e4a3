#!/usr/bin/env bash
# Lists every function in src/ longer than LIMIT lines (default 150): clang-tidy's
# readability-function-size check on the build's compile_commands.json (configure first:
# cmake -S . -B build), headers and .inl files under src/ included. Exit 1 when one is found.
# Usage: bash scripts/function_sizes.sh [LIMIT] [FILE...]
set -euo pipefail
cd "$(dirname "$0")/.."
LIMIT=${1:-150}
shift || true
BUILD=${BUILD_DIR:-build}
[ -f "$BUILD/compile_commands.json" ] || { echo "function_sizes: $BUILD/compile_commands.json: missing (run cmake -S . -B $BUILD)" >&2; exit 2; }
command -v clang-tidy > /dev/null || { echo "function_sizes: clang-tidy: not installed (apt-get install clang-tidy)" >&2; exit 2; }
if [ $# -gt 0 ]; then FILES=("$@"); else mapfile -t FILES < <(find src -name '*.cpp' | sort); fi
CONFIG="{Checks: '-*,readability-function-size', CheckOptions: [{key: readability-function-size.LineThreshold, value: $LIMIT}]}"
out=$(clang-tidy -p "$BUILD" --quiet --header-filter='.*/src/.*' --config="$CONFIG" "${FILES[@]}" 2>/dev/null | grep -A1 "warning: function" || true)
if [ -n "$out" ]; then
  echo "$out" | grep "warning:" | sed 's/ \[readability-function-size\]//' | sort -u
  echo "function_sizes: functions over $LIMIT lines (above)" >&2
  exit 1
fi
echo "function_sizes: no function in ${#FILES[@]} files is over $LIMIT lines"
