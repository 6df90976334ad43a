#!/usr/bin/env bash
# README command 1: installs and builds as needed, then renders the project's example scene
# (a Cornell box from its published measurements) to out/cornell-box.{exr,png,json} with
# lightcuts, which evaluates a small fraction of the lighting matrix (see the stats JSON).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
# Only the `lightfarm` program and what it links: the tests and benchmarks are built by test.sh.
LIGHTFARM_TARGETS=lightfarm bash "$root/scripts/build.sh"
mkdir -p "$root/out"
"$root/build/lightfarm" render "$root/scenes/cornell-box/scene.pbrt" \
  --method lightcuts --resolution 256x256 --spp 4 --lights 20000 \
  --out "$root/out/cornell-box.exr" --stats "$root/out/cornell-box.json" "$@"
echo "wrote $root/out/cornell-box.exr, .png and .json"
