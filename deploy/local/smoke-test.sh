#!/usr/bin/env bash
# Starts a local farm, submits the example scene, checks the result equals the embedded render
# bit for bit, stops the farm. Exit code 0 on success.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=${LIGHTFARM_BIN:-$root/build}
run_dir=$(mktemp -d)
trap '"$root/deploy/local/stop.sh" "$run_dir"; rm -rf "$run_dir"' EXIT
addr=$("$root/deploy/local/start.sh" --workers 2 --port "${PORT:-7170}" --run-dir "$run_dir")
args=(--resolution 32x32 --lights 2000 --seed 1)
"$bin/lightfarm" submit "$root/scenes/cornell-box/scene.pbrt" --server "$addr" --wait --quiet \
  --out "$run_dir/farm.exr" "${args[@]}"
"$bin/lightfarm" render "$root/scenes/cornell-box/scene.pbrt" --workers 2 --quiet \
  --out "$run_dir/embedded.exr" "${args[@]}"
"$bin/lightfarm" compare "$run_dir/embedded.exr" "$run_dir/farm.exr" | tee /dev/stderr | grep -q "^rel_l2=0 "
echo "smoke test passed"
