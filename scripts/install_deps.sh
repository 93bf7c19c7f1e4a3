#!/usr/bin/env bash
# Installs refgrasp's build and test dependencies from Debian 12 packages. Idempotent.
set -euo pipefail
PKGS=(build-essential cmake pkg-config
      libopencv-dev libvisp-dev libeigen3-dev libdc1394-dev
      libgtest-dev libgmock-dev libbenchmark-dev
      libyaml-cpp-dev nlohmann-json3-dev libcli11-dev
      cyclonedds-dev cyclonedds-tools)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PKGS[@]} packages already installed"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install_deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y --no-install-recommends "${missing[@]}"
