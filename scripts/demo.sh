#!/usr/bin/env bash
# The main job: installs dependencies (Debian 12 packages), builds the apps (Release) and runs the
# simulated search demo on config/scenarios/${SCENARIO:-table_single}.yaml. Pictures and a JSON-lines
# log go to out/demo/. Extra arguments are passed to build/app/sim_search_demo (see --help).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
JOBS=${JOBS:-$(nproc)}
BUILD=${BUILD_DIR:-build}
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release > /dev/null
echo "demo: building sim_search_demo (first build takes a few minutes)"
cmake --build "$BUILD" -j "$JOBS" --target sim_search_demo detect_object
"$BUILD"/app/sim_search_demo --scenario "config/scenarios/${SCENARIO:-table_single}.yaml" \
  --out out/demo "$@"
