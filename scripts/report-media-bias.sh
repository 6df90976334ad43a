#!/usr/bin/env bash
# Generates docs/methods/media-bias.md: where the media transport's image mean departs from the
# path tracer's, split by what could cause it. Every number comes from a command this script
# runs; never edit the output by hand: re-run.
#   1. The cloud (scenes/cloud) at maxdepth 1..4, 64²: brute force with virtual ray lights and
#      with medium VPLs from the same light paths, no clamp (so nothing is lost or given back),
#      each with three light sets (seeds), against `path`; a second `path` seed says how far two
#      path-traced means differ. One light set's mean is itself a random draw: the spread over
#      the seeds says how far it goes.
#   2. The same at maxdepth 3 in a homogeneous sphere of the cloud's coefficients (no density
#      grid: the density-aware element sampling has nothing to do), and with 16 samples per
#      element instead of 2 on one light set (an element estimator's bias would move with the
#      count; the light set's draw would not).
#   3. The cloud as shipped (maxdepth 4) at 128²: the clamp, its compensation and
#      adaptive-completion, against `path` at 4096 spp; the unclamped image at three light sets.
# Usage: scripts/report-media-bias.sh   (about 25 minutes on 2 cores)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
. "$root/scripts/report-lib.sh"
report_begin
out="$root/docs/methods/media-bias.md"
cloud="$root/scenes/cloud"

# mean IMAGE: the mean over all pixels and channels.
mean() {
  "$py" - "$1" <<'PY'
import sys, OpenImageIO as oiio
s = oiio.ImageBufAlgo.computePixelStats(oiio.ImageBuf(sys.argv[1]))
print(f"{sum(s.avg[:3]) / 3:.8g}")
PY
}
ratio() { "$py" -c "import sys; print(f'{float(sys.argv[1]) / float(sys.argv[2]):.4f}')" "$1" "$2"; }
render() { "$lf" render "$@" --quiet; }

# scene_at DIR DEPTH [homogeneous]: the cloud with another maxdepth (the density grid linked in).
scene_at() {
  mkdir -p "$1"
  ln -sf "$cloud/wdas_cloud_sixteenth.nvdb" "$1/"
  local edit=(-e "s/maxdepth\" \[ 4 \]/maxdepth\" [ $2 ]/")
  [ "${3:-}" = homogeneous ] && edit+=(-e 's/"string type" \[ "nanovdb" \]/"string type" [ "homogeneous" ]/'
                                      -e '/wdas_cloud_sixteenth/d')
  sed "${edit[@]}" "$cloud/scene.pbrt" > "$1/scene.pbrt"
}

# spread VALUES...: "mean ± standard deviation" (one value: itself).
spread() {
  "$py" -c "import statistics as s, sys; v = [float(x) for x in sys.argv[1:]]; print(f'{s.mean(v):.4f} ± {s.stdev(v):.4f}' if len(v) > 1 else f'{v[0]:.4f}')" "$@"
}

# depth_row LABEL DIR RES SEEDS [extra brute params...]: path (two seeds), brute with VRLs and with
# VPLs on each light seed; the ratios' mean ± deviation over the seeds.
depth_row() {
  local label=$1 dir=$2 res=$3 seeds=$4
  shift 4
  render "$dir/scene.pbrt" --method path --resolution "$res" --spp 1024 --seed 5 --out "$dir/path.exr"
  render "$dir/scene.pbrt" --method path --resolution "$res" --spp 1024 --seed 6 --out "$dir/path2.exr"
  local p vrl=() vpl=()
  p=$(mean "$dir/path.exr")
  for seed in $seeds; do
    render "$dir/scene.pbrt" --method brute --resolution "$res" --seed "$seed" --param clamp=0 "$@" --out "$dir/vrl.exr"
    render "$dir/scene.pbrt" --method brute --resolution "$res" --seed "$seed" --param clamp=0 --param media_lights=vpl \
      "$@" --out "$dir/vpl.exr"
    vrl+=("$(ratio "$(mean "$dir/vrl.exr")" "$p")")
    vpl+=("$(ratio "$(mean "$dir/vpl.exr")" "$p")")
  done
  echo "| $label | $(echo "$seeds" | wc -w) | $p | $(ratio "$(mean "$dir/path2.exr")" "$p") | $(spread "${vrl[@]}") | $(spread "${vpl[@]}") |"
}

rows=()
for d in 1 2 3 4; do
  scene_at "$work/d$d" "$d"
  seeds="0 1 2"
  [ "$d" = 1 ] && seeds=0  # the camera-side direct light alone: no virtual light
  rows+=("$(depth_row "cloud, maxdepth $d" "$work/d$d" 64x64 "$seeds")")
done
scene_at "$work/h3" 3 homogeneous
rows+=("$(depth_row "homogeneous sphere, maxdepth 3" "$work/h3" 64x64 "0 1 2")")
rows+=("$(depth_row "cloud, maxdepth 3, 16 samples per element" "$work/d3" 64x64 0 --param segment_samples=16)")
rows+=("$(depth_row "cloud, maxdepth 3, 2 samples per element (the default)" "$work/d3" 64x64 0)")

# --- 3. The shipped cloud at 128² ---------------------------------------------------------------
full="$work/full"
mkdir -p "$full"
render "$cloud/scene.pbrt" --method path --resolution 128x128 --spp 4096 --seed 5 --out "$full/path.exr"
p=$(mean "$full/path.exr")
full_rows=()
full_case() {
  local label=$1 name=$2
  shift 2
  render "$cloud/scene.pbrt" --resolution 128x128 "$@" --out "$full/$name.exr" --stats "$full/$name.json"
  local lost comp
  lost=$("$py" -c "import json, sys; print(f\"{json.load(open(sys.argv[1]))['clamp']['energy_lost_fraction']:.4f}\")" "$full/$name.json")
  comp=$("$py" -c "import json, sys; print(f\"{json.load(open(sys.argv[1]))['clamp']['compensated_fraction']:.4f}\")" "$full/$name.json")
  full_rows+=("| $label | \`$*\` | $(ratio "$(mean "$full/$name.exr")" "$p") | $lost | $comp |")
}
for seed in 0 1 2; do
  full_case "brute force, no clamp, light seed $seed" "noclamp$seed" --method brute --param clamp=0 --seed "$seed"
done
full_case "brute force, the clamp, no compensation" nocomp --method brute --param media_compensation=0
full_case "brute force, the clamp compensated (the default)" brute --method brute
full_case "adaptive-completion, defaults" ac --method adaptive-completion

{
  echo "# The media transport's mean against the path tracer's"
  echo
  echo "Generated by \`scripts/report-media-bias.sh\` on $(date -u +%Y-%m-%d) at commit $(git -C "$root" rev-parse --short HEAD)"
  echo "($(nproc) cores). Each number is an image mean over \`path\`'s mean at the same resolution (1 is"
  echo "exact); the means are over every pixel and channel, so a pixel's noise averages out and what is"
  echo "left is bias."
  echo
  echo "## By depth, and virtual ray lights against medium VPLs"
  echo
  echo "64², no clamp (\`--param clamp=0\`: nothing is taken or given back). \`path\` at 1024 spp, seed 5"
  echo "(its mean in the second column) and seed 6 (how far two path-traced means differ). \`VRL\`: brute"
  echo "force over the virtual ray lights (the default media lights); \`VPL\`: brute force over medium"
  echo "VPLs at the collisions of the same light paths (\`--param media_lights=vpl\`), each over the light"
  echo "sets (\`--seed\` 0, 1, 2: mean ± standard deviation of the ratio). At maxdepth 1 both are the"
  echo "camera-side direct light alone."
  echo
  echo "| scene | light sets | path mean | path, another seed | VRL | VPL |"
  echo "|---|---|---|---|---|---|"
  printf '%s\n' "${rows[@]}"
  echo
  echo "## The cloud as shipped, 128²"
  echo
  echo "maxdepth 4; against \`path\` at 4096 spp (seed 5). \`lost\` and \`compensated\` are the stats'"
  echo "\`clamp.energy_lost_fraction\` and \`clamp.compensated_fraction\`."
  echo
  echo "| render | options | mean / path | lost | compensated |"
  echo "|---|---|---|---|---|"
  printf '%s\n' "${full_rows[@]}"
} > "$out"
repo_relative "$out"
echo "wrote $out"
