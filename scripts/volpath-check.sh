#!/bin/bash
# Compares lightfarm brute with the independent path tracer (build/lightfarm-volpath-check) on
# modified copies of volumetric-caustic (docs/rendering.md, "Open: volumetric-caustic"): the
# sphere glass (as shipped), black diffuse, or removed, at several maxdepths. Prints the mean RGB
# of the whole image and of a few regions for each renderer and for the reference.
#
# usage: scripts/volpath-check.sh [OUT_DIR] [SPHERE_VARIANTS] [DEPTHS]
#   defaults: /tmp/volpath-check "glass black none" "1 2 3 7"
# env: RES (64), LIGHTS (4000), SPP_PT (4096), BUILD (build), SHARED (../shared)
# Costs on 2 shared cores, 64×64: lightfarm 1-1.5 min, path tracer ~1 min per case.
set -euo pipefail
out=${1:-/tmp/volpath-check}
variants=${2:-"glass black none"}
depths=${3:-"1 2 3 7"}
res=${RES:-64}
lights=${LIGHTS:-4000}
spp_pt=${SPP_PT:-4096}
build=${BUILD:-build}
shared=${SHARED:-$(cd "$(dirname "$0")/../.." && pwd)/shared}
src=$shared/scenes/volumetric-caustic/scene.pbrt
mkdir -p "$out"

# Regions at 64×64 (scaled for other sizes): rows 8-63 (no light pixels), left/right wall, back
# wall lit directly, gas below the sphere, floor, gas next to the light.
regions="below:64x56+0+8 lwall:5x40+1+12 rwall:5x40+58+12 back:10x10+40+15 shadow:8x12+18+36
floor:24x4+20+59 glow:8x6+28+7"
scaled_regions() {
  for r in $regions; do
    name=${r%%:*} g=${r#*:}
    IFS='x+' read -r w h x y <<<"$g"
    echo "$name:$((w * res / 64))x$((h * res / 64))+$((x * res / 64))+$((y * res / 64))"
  done
}
region_means() {  # image → one line per region: name r g b
  local img=$1
  printf "all "; oiiotool "$img" --printstats | awk '/Stats Avg/{print $3, $4, $5}'
  for r in $(scaled_regions); do
    printf "%s " "${r%%:*}"
    oiiotool "$img" --cut "${r#*:}" --printstats | awk '/Stats Avg/{print $3, $4, $5}'
  done
}

write_scene() {  # variant depth → scene path
  local variant=$1 depth=$2 dst=$out/vc_${1}_d$2.pbrt
  python3 - "$src" "$dst" "$variant" "$depth" <<'EOF'
import re, sys
src, dst, variant, depth = sys.argv[1:]
s = open(src).read()
s = re.sub(r'"integer maxdepth" \[ \d+ \]', '"integer maxdepth" [ %s ]' % depth, s)
glass = '''"string type" [ "dielectric" ]
    "float eta" [ 1.5 ]
    "bool remaproughness" [ false ]'''
if variant == 'black':
    assert glass in s
    s = s.replace(glass, '"string type" [ "diffuse" ]\n    "rgb reflectance" [ 0 0 0 ]')
elif variant == 'none':
    i = s.index('AttributeBegin\n    MediumInterface "" "gas"\n    NamedMaterial "Sphere"')
    j = s.index('AttributeEnd\nAttributeEnd', i) + len('AttributeEnd\nAttributeEnd')
    s = s[:i] + s[j:]
open(dst, 'w').write(s)
EOF
  echo "$dst"
}

ref=$out/reference_${res}.exr
oiiotool "$(dirname "$src")/reference.exr" --resize:filter=box "${res}x${res}" -o "$ref"
echo "== reference (box-averaged to ${res}x${res})"
region_means "$ref"
for variant in $variants; do
  for depth in $depths; do
    scene=$(write_scene "$variant" "$depth")
    tag=${variant}_d$depth
    "$build/lightfarm" render "$scene" --method brute --lights "$lights" \
      --resolution "${res}x${res}" --filter box --out "$out/lf_$tag.exr" --quiet
    "$build/lightfarm-volpath-check" "$scene" --resolution "${res}x${res}" --spp "$spp_pt" \
      --out "$out/pt_$tag.exr" > "$out/pt_$tag.txt"
    echo "== sphere $variant, maxdepth $depth: region  lightfarm-brute  |  path tracer"
    paste -d'|' <(region_means "$out/lf_$tag.exr") <(region_means "$out/pt_$tag.exr")
  done
done
