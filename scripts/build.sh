#!/usr/bin/env bash
# Installs the Debian packages (if missing), configures and builds lightfarm (Release, warnings
# on; -Werror when CI is set). Idempotent: a second run rebuilds only what changed.
# Usage: scripts/build.sh [build-dir] [extra cmake args...]
# Env: LIGHTFARM_TARGETS (space-separated): build only these targets (default: everything).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
shift || true
bash "$root/scripts/install-deps.sh"
werror=OFF
[ -n "${CI:-}" ] && werror=ON
if [ ! -f "$build/build.ninja" ]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DLIGHTFARM_WERROR=$werror "$@"
fi
targets=()
for t in ${LIGHTFARM_TARGETS:-}; do targets+=(--target "$t"); done
cmake --build "$build" --parallel "$(nproc)" "${targets[@]}"
