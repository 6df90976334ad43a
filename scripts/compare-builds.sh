#!/usr/bin/env bash
# Renders every shared scene and every project scene with every method (auto and each one the old
# build's `lightfarm methods` lists) using two lightfarm builds, and compares the pixels (oiiotool, zero tolerance) and the stats JSON (times
# removed; keys only the new build has are listed, not failures). For refactors that must not
# change a bit: `scripts/compare-builds.sh OLD/lightfarm build/lightfarm`. Exit 1 when anything
# differs.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
shared=${LIGHTFARM_SHARED:-$root/../shared}
[ $# -eq 2 ] || { echo "usage: $0 OLD_LIGHTFARM NEW_LIGHTFARM" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scenes=()
for s in "$shared"/scenes/*/scene.pbrt "$root"/scenes/*/scene.pbrt; do [ -f "$s" ] && scenes+=("$s"); done
# The methods: auto, then every one the old build lists (a line without indentation, the renderer-wide
# "every method" line aside).
methods=(auto $("$1" methods | grep -E '^[a-z][a-z-]*$'))
compared=0 differ=0
for scene in "${scenes[@]}"; do
  name=$(basename "$(dirname "$scene")")-$(echo "$scene" | md5sum | cut -c1-6)
  for method in "${methods[@]}"; do
    for side in old new; do
      bin=$1; [ $side = new ] && bin=$2
      "$bin" render "$scene" --method $method --resolution 32x24 --spp 2 --lights 1000 --seed 3 \
        --threads 2 --out "$tmp/$side-$name-$method.exr" --stats "$tmp/$side-$name-$method.json" >/dev/null 2>&1 \
        || { echo "$side build failed on $scene ($method)"; differ=$((differ + 1)); continue 2; }
    done
    compared=$((compared + 1))
    if ! oiiotool "$tmp/old-$name-$method.exr" "$tmp/new-$name-$method.exr" --fail 0 --failpercent 0 --diff 2>&1 | grep -q '^PASS'; then
      echo "pixels differ: $scene ($method)"; differ=$((differ + 1))
    fi
    if ! python3 - "$tmp/old-$name-$method.json" "$tmp/new-$name-$method.json" <<'PY'
import json, sys
# Every value the old build reported (times removed) must be the same in the new one; keys only
# the new build reports are listed, not counted as differences.
def flat(x, prefix=""):
    if isinstance(x, dict):
        out = {}
        for k, v in x.items():
            if k != "time" and not k.endswith("_s") and k != "seconds":
                out.update(flat(v, prefix + k + "."))
        return out
    return {prefix.rstrip("."): x}
old, new = (flat(json.load(open(p))) for p in sys.argv[1:3])
bad = [k for k in old if k not in new or new[k] != old[k]]
for k in bad[:5]:
    print(f"  {k}: {old[k]} -> {new.get(k, '(missing)')}")
added = sorted(set(new) - set(old))
if added:
    print("  new keys: " + ", ".join(added))
sys.exit(1 if bad else 0)
PY
    then
      echo "stats differ: $scene ($method)"; differ=$((differ + 1))
    fi
  done
done
echo "compared $compared renders (${#scenes[@]} scenes x ${#methods[@]} methods: ${methods[*]}): $differ differences"
[ $differ -eq 0 ]
