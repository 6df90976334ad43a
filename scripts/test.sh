#!/usr/bin/env bash
# README command 2: installs and builds as needed, then runs the whole test suite with ctest.
# The shared scenes are looked up in $LIGHTFARM_SHARED, else ../shared beside the repository.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/build.sh"
export LIGHTFARM_SHARED=${LIGHTFARM_SHARED:-$(cd "$root/.." && pwd)/shared}
cd "$root/build"
ctest --output-on-failure --timeout 1800 -j "$(nproc)" "$@"
