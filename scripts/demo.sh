#!/usr/bin/env bash
# The main job: installs dependencies (Debian 12 packages), builds the apps (Release) and runs
# search-approach-grasp on the simulated enon with config/scenarios/${SCENARIO:-table_single}.yaml:
# the enon finds the target, drives to it, aligns its gripper by visual servoing and grasps it.
# Writes out/demo/grasp.mp4 (three panels: the camera view annotated, the robot seen from outside,
# the map from above) and out/demo/log/ (a recording of the frames used plus control.jsonl);
# prints the summary line. Extra arguments go to
# build/app/enon_grasp (see --help), e.g. --oracle or --seed 4.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install_deps.sh
JOBS=${JOBS:-$(nproc)}
BUILD=${BUILD_DIR:-build}
cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release > /dev/null
echo "demo: building enon_grasp (first build takes a few minutes)"
cmake --build "$BUILD" -j "$JOBS" --target enon_grasp pose_replay detect_object
mkdir -p out/demo
rm -rf out/demo/log
"$BUILD"/app/enon_grasp --backend sim --scenario "config/scenarios/${SCENARIO:-table_single}.yaml" \
  --video out/demo/grasp.mp4 --log out/demo/log "$@"
