#!/usr/bin/env bash
# The dependency rules of docs/architecture.md, checked on the source tree (ctest: Layout.*).
# Usage: tests/layout_check.sh [SOURCE_DIR]. Prints every violation; exit 1 if there is one.
set -u
cd "${1:-$(dirname "$0")/..}" || exit 2
fail=0
violation() { echo "layout: $1"; fail=1; }

# The HAL knows no backend: no backend namespace or header in src/robot/*.{h,cpp}
# (backends.cpp and sources.cpp, which build every backend and camera source by name, are the
# refgrasp_robot_backends library).
hits=$(grep -lnE "namespace refgrasp::(sim|dds|files|dc1394)" src/robot/*.h 2>/dev/null)
[ -z "$hits" ] || violation "backend namespace in HAL headers: $hits"
for f in src/robot/*.h src/robot/*.cpp; do
  case "$(basename "$f")" in backends.cpp|sources.cpp) continue ;; esac
  grep -Hn '#include "robot/[a-z0-9_]*/' "$f" && violation "$f includes a backend header"
done
# Backends never include another backend.
for d in src/robot/*/; do
  b=$(basename "$d")
  grep -HnE "#include \"robot/[a-z0-9_]+/" "$d"*.h "$d"*.cpp 2>/dev/null | grep -v "\"robot/$b/" &&
    violation "backend $b includes another backend"
done
# A backend knows the HAL and core only: never the detector or servo.
grep -HnE '#include [<"](detector|servo)/' src/robot/*/*.h src/robot/*/*.cpp 2>/dev/null &&
  violation "a robot backend includes the detector or servo"
# core depends on nothing of ours; detector never on ViSP, robot or servo; servo never on a backend.
grep -HnE '#include "(detector|servo|robot)/' src/core/* && violation "core includes another module"
grep -HnE '#include [<"]visp3?/|#include "(servo|robot)/' src/detector/* && violation "detector includes ViSP, servo or robot"
grep -HnE '#include "robot/[a-z0-9_]+/' src/servo/* && violation "servo includes a backend header"
# reference (make_reference) builds on core and the detector only (and ViSP), never robot or servo.
grep -HnE '#include "(servo|robot)/' src/reference/* && violation "reference includes robot or servo"
# eval (the evaluation against the classic pipeline) sits on top: no other module includes it.
grep -HnE '#include "eval/' src/core/* src/detector/* src/servo/* src/reference/* src/robot/*.h src/robot/*.cpp src/robot/*/*.h src/robot/*/*.cpp 2>/dev/null &&
  violation "a module includes eval"
[ $fail -eq 0 ] && echo "layout: ok"
exit $fail
