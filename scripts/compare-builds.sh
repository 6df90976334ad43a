#!/usr/bin/env bash
# Renders every shared scene and every project scene with auto, brute, mrcs and path using two
# lightfarm builds, and compares the pixels (oiiotool, zero tolerance) and the stats JSON (times
# removed). For refactors that must not change a bit: `scripts/compare-builds.sh OLD/lightfarm
# build/lightfarm`. Exit 1 when anything differs.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
shared=${LIGHTFARM_SHARED:-$root/../shared}
[ $# -eq 2 ] || { echo "usage: $0 OLD_LIGHTFARM NEW_LIGHTFARM" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scenes=()
for s in "$shared"/scenes/*/scene.pbrt "$root"/scenes/*/scene.pbrt; do [ -f "$s" ] && scenes+=("$s"); done
compared=0 differ=0
for scene in "${scenes[@]}"; do
  name=$(basename "$(dirname "$scene")")-$(echo "$scene" | md5sum | cut -c1-6)
  for method in auto brute mrcs path; do
    for side in old new; do
      bin=$1; [ $side = new ] && bin=$2
      "$bin" render "$scene" --method $method --resolution 32x24 --spp 2 --lights 1000 --seed 3 \
        --threads 2 --out "$tmp/$side-$name-$method.exr" --stats "$tmp/$side-$name-$method.json" >/dev/null 2>&1 \
        || { echo "$side build failed on $scene ($method)"; differ=$((differ + 1)); continue 2; }
      python3 - "$tmp/$side-$name-$method.json" <<'PY'
import json, sys
def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if k != "time" and not k.endswith("_s")}
    return x
path = sys.argv[1]
json.dump(strip(json.load(open(path))), open(path + ".cmp", "w"), sort_keys=True, indent=1)
PY
    done
    compared=$((compared + 1))
    if ! oiiotool "$tmp/old-$name-$method.exr" "$tmp/new-$name-$method.exr" --fail 0 --failpercent 0 --diff 2>&1 | grep -q '^PASS'; then
      echo "pixels differ: $scene ($method)"; differ=$((differ + 1))
    fi
    if ! cmp -s "$tmp/old-$name-$method.json.cmp" "$tmp/new-$name-$method.json.cmp"; then
      echo "stats differ: $scene ($method)"; diff "$tmp/old-$name-$method.json.cmp" "$tmp/new-$name-$method.json.cmp" | head -5
      differ=$((differ + 1))
    fi
  done
done
echo "compared $compared renders (${#scenes[@]} scenes x 4 methods): $differ differences"
[ $differ -eq 0 ]
