#!/usr/bin/env bash
# Generates docs/clamp.md: what the geometry clamp and the element bound remove, and what the
# path-traced compensation gives back (docs/rendering.md, "The clamp"). Every number comes from a
# command this script runs; never edit the output by hand: re-run.
#   1. A furnace (a closed box, every face an emitter of radiance 1 and reflectance 0.5; the
#      exact radiance is 1 + ρ + ρ² at maxdepth 2): the image mean against the closed form.
#      And the expected loss on a render's own receivers in closed form against what the
#      compensation traced (the unit test WhatItAddsIsTheFurnacesExpectedLossInClosedForm, whose
#      recorded properties are read back).
#   2. cornell-box at 128², 20000 lights, five seeds: the loss the VPLs measure, its expectation
#      by the probe (--param clamp_probe, 2048 more light sets), what the compensation traces,
#      and the difference.
#   3. scenes/glossy-plane at roughness 0.02 (sharp-lobe split off and at its default) against
#      the path tracer, for element bounds bsdf_clamp = 0 (off), 1 (the default), 0.1 and 0.01.
#   4. veach-mis, the default render at 320×180 against a path-traced truth, for the same bounds.
# Usage: scripts/report-clamp.sh   (about 15 minutes on 2 cores, 5 more without a cached truth)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
shared=${LIGHTFARM_SHARED:-$(cd "$root/.." && pwd)/shared}
. "$root/scripts/report-lib.sh"
report_begin
out="$root/docs/clamp.md"
seeds=(0 1 2 3 4)

# json FILE EXPR: EXPR evaluated on the stats JSON `d`.
json() { "$py" -c "import json, sys; d = json.load(open(sys.argv[1])); print($2)" "$1"; }
# mean_lum IMAGE: mean luminance over all pixels.
mean_lum() {
  "$py" - "$1" <<'PY'
import sys, OpenImageIO as oiio
s = oiio.ImageBufAlgo.computePixelStats(oiio.ImageBuf(sys.argv[1]))
print(f"{0.2126 * s.avg[0] + 0.7152 * s.avg[1] + 0.0722 * s.avg[2]:.8f}")
PY
}
# mean_sd VALUES...: "mean ± standard deviation" of the values (sample deviation).
mean_sd() {
  "$py" -c "import statistics as s, sys; v = [float(x) for x in sys.argv[1:]]; print(f'{s.mean(v):+.4f} ± {s.stdev(v):.4f}' if len(v) > 1 else f'{v[0]:+.4f}')" "$@"
}

# --- 1. The furnace ---------------------------------------------------------------------------
furnace="$work/furnace.pbrt"
cat > "$furnace" <<'EOF'
Film "rgb" "integer xresolution" [32] "integer yresolution" [32]
PixelFilter "box"
Integrator "path" "integer maxdepth" [2]
LookAt 0.5 0.5 0.5  0 0 0  0 1 0
Camera "perspective" "float fov" [100]
WorldBegin
AreaLightSource "diffuse" "rgb L" [1 1 1] "bool twosided" true
Material "diffuse" "rgb reflectance" [0.5 0.5 0.5]
Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 1 1 0 0 1 0  0 0 1 1 0 1 1 1 1 0 1 1]
  "integer indices" [0 1 2 0 2 3  4 6 5 4 7 6  0 4 5 0 5 1  3 2 6 3 6 7  0 3 7 0 7 4  1 5 6 1 6 2]
EOF
exact=1.75
furnace_rows=()
for lights in 4000 20000; do
  for cfg in "0.01 0" "0.01 4" "0.2 0" "0.2 16"; do
    read -r clamp comp <<<"$cfg"
    errs=(); lost=(); comped=()
    for seed in "${seeds[@]}"; do
      f="$work/furnace-$lights-$clamp-$comp-$seed"
      "$lf" render "$furnace" --quiet --method brute --spp 4 --lights "$lights" --seed "$seed" \
        --param "clamp=$clamp" --param "clamp_compensation=$comp" --out "$f.exr" --stats "$f.json"
      errs+=("$("$py" -c "print(($(mean_lum "$f.exr")) / $exact - 1)")")
      lost+=("$(json "$f.json" "d['clamp']['energy_lost_fraction']")")
      comped+=("$(json "$f.json" "d['clamp']['compensated_fraction']")")
    done
    furnace_rows+=("| $lights | $clamp | $comp | $(mean_sd "${errs[@]}") | $(mean_sd "${lost[@]}") | $(mean_sd "${comped[@]}") |")
  done
done

# The closed form (tests/unit/test_clamp_compensation.cpp): the test's recorded properties.
cmake --build "$build" --target lightfarm_unit_tests >/dev/null
"$build/lightfarm_unit_tests" --gtest_filter='ClampCompensation.WhatItAddsIsTheFurnacesExpectedLossInClosedForm' \
  --gtest_output="json:$work/closed-form.json" >/dev/null
closed_rows=()
while read -r line; do closed_rows+=("$line"); done < <("$py" - "$work/closed-form.json" <<'PY'
import json, sys
t = json.load(open(sys.argv[1]))["testsuites"][0]["testsuite"][0]
assert t.get("result", "COMPLETED") == "COMPLETED" and not t.get("failures"), "the closed-form test failed"
for clamp in ("0.010000", "0.200000"):
    e, c = float(t[f"clamp_{clamp}_expected_loss"]), float(t[f"clamp_{clamp}_compensated"])
    print(f"| {float(clamp):g} | {100 * e:.4f}% | {100 * c:.4f}% | {100 * (e - c):+.4f}% |")
PY
)

# --- 2. cornell-box ---------------------------------------------------------------------------
probe_sets=2048
cornell_rows=(); cornell_after=()
for seed in "${seeds[@]}"; do
  f="$work/cornell-$seed"
  "$lf" render "$shared/scenes/cornell-box/scene.pbrt" --quiet --method brute --resolution 128x128 \
    --lights 20000 --seed "$seed" --param clamp_compensation=16 --param "clamp_probe=$probe_sets" \
    --out "$f.exr" --stats "$f.json"
  cornell_rows+=("$(json "$f.json" "'| $seed | %.4f%% | %.4f%% ± %.4f%% | %.3f | %.4f%% | %+.4f%% | %+.4f%% | %d | %.1f s | %.1f s |' % (100 * d['clamp']['energy_lost_fraction'], 100 * d['clamp']['probe']['expected_loss_fraction'], 100 * d['clamp']['probe']['expected_loss_stderr'], d['clamp']['probe']['largest_light_set_share'], 100 * d['clamp']['compensated_fraction'], 100 * d['clamp']['energy_lost_after_compensation'], 100 * d['clamp']['probe']['expected_loss_after_compensation'], d['clamp']['bound_elements'], d['time']['total_s'], d['clamp']['probe']['seconds'])")")
  cornell_after+=("$(json "$f.json" "100 * d['clamp']['probe']['expected_loss_after_compensation']")")
done
cornell_median=$("$py" -c "import statistics as s, sys; print(f'{s.median(float(x) for x in sys.argv[1:]):+.4f}%')" "${cornell_after[@]}")
cornell_mean=$("$py" -c "import statistics as s, sys; v = [float(x) for x in sys.argv[1:]]; print(f'{s.mean(v):+.4f}% ± {s.stdev(v) / len(v) ** 0.5:.4f}%')" "${cornell_after[@]}")

# --- 3. glossy-plane --------------------------------------------------------------------------
glossy="$root/scenes/glossy-plane/scene.pbrt"  # its plane's roughness is 0.02
"$lf" render "$glossy" --quiet --method path --spp 1024 --seed 3 --out "$work/glossy-truth.exr"
# regions TRUTH IMAGE: blob, backdrop and plane means over the truth's, and backdrop specks
# (pixels brighter than 3× the truth's 3×3 mean around them), as in tests/scenes/test_sharp_lobes.cpp.
regions() {
  "$py" - "$1" "$2" <<'PY'
import sys, numpy as np, OpenImageIO as oiio
def lum(p):
    a = oiio.ImageBuf(p).get_pixels(oiio.FLOAT)[:, :, :3]
    return 0.2126 * a[..., 0] + 0.7152 * a[..., 1] + 0.0722 * a[..., 2]
t, m = lum(sys.argv[1]), lum(sys.argv[2])
cells = []
for x0, y0, w, h in [(16, 24, 16, 8), (0, 4, 48, 10), (0, 16, 48, 6)]:
    cells.append(f"{m[y0:y0 + h, x0:x0 + w].mean() / t[y0:y0 + h, x0:x0 + w].mean():.3f}")
H, W = t.shape
specks = sum(int(m[y, x] > 3 * t[max(0, y - 1):y + 2, max(0, x - 1):x + 2].mean())
             for y in range(4, 14) for x in range(0, 48))
print(" | ".join(cells + [str(specks)]))
PY
}
rel_l1() { "$lf" compare --resize --json "$1" "$2" | "$py" -c "import json, sys; print(f\"{json.load(sys.stdin)['rel_l1']:.4f}\")"; }
glossy_rows=()
for split in off default; do
  split_param=(); [ $split = off ] && split_param=(--param sharp_roughness=0)
  for b in 0 1 0.1 0.01; do
    for seed in 3 4; do
      f="$work/glossy-$split-$b-$seed"
      "$lf" render "$glossy" --quiet --method brute --spp 16 --lights 2000 --seed "$seed" "${split_param[@]}" \
        --param caustic_photons=50000 --param "bsdf_clamp=$b" --param clamp_compensation=16 \
        --out "$f.exr" --stats "$f.json"
      glossy_rows+=("| $split | $b | $seed | $(regions "$work/glossy-truth.exr" "$f.exr") | $(rel_l1 "$work/glossy-truth.exr" "$f.exr") | $(json "$f.json" "'%d | %.3f%% | %.3f%% | %.1f s' % (d['clamp']['bound_elements'], 100 * d['clamp']['bound_lost_fraction'], 100 * d['clamp']['compensated_fraction'], d['time']['total_s'])") |")
    done
  done
done

# --- 4. veach-mis -----------------------------------------------------------------------------
veach="$shared/scenes/veach-mis/scene.pbrt"
truth="$build/default-runs/veach-mis/truth.exr"  # scripts/report-default.sh's, when it ran
truth_label="scripts/report-default.sh's path-traced truth (build/default-runs/veach-mis/truth.exr, 1280×720, area-averaged)"
if [ ! -f "$truth" ]; then
  truth="$work/veach-truth.exr"
  "$lf" render "$veach" --quiet --method path --resolution 320x180 --seed 7 --until-noise 0.01 --time-limit 300 \
    --out "$truth" --stats "$work/veach-truth.json"
  truth_label="$(json "$work/veach-truth.json" "'path-traced here at 320×180 (\`--method path --until-noise 0.01 --time-limit 300\`): %d passes in %.0f s, relative standard error of its mean %.4f' % (d['passes'], sum(d['pass_times_s']), d['noise']['rel_stderr'])")"
fi
veach_rows=()
for b in 0 1 0.1 0.01; do
  f="$work/veach-$b"
  "$lf" render "$veach" --quiet --resolution 320x180 --param "bsdf_clamp=$b" --out "$f.exr" --stats "$f.json"
  veach_rows+=("| $b | $(json "$f.json" "d['method']") | $(rel_l1 "$truth" "$f.exr") | $(json "$f.json" "'%d | %.3f%% | %.3f%% | %.1f s' % (d['clamp']['bound_elements'], 100 * d['clamp']['bound_lost_fraction'], 100 * d['clamp']['compensated_fraction'], d['time']['total_s'])") |")
done

{
  echo "# The clamp, the element bound and their compensation"
  echo
  echo "Generated by \`scripts/report-clamp.sh\` on $(date -u +%Y-%m-%d) at commit"
  echo "\`$(git -C "$root" rev-parse --short HEAD)\` on $(nproc) cores. The method: docs/rendering.md, \"The clamp\"."
  echo "\`lost\` is the stats' \`clamp.energy_lost_fraction\` (what the clamp and the bound removed from the"
  echo "visible elements, as a share of the unclamped light), \`compensated\` is \`clamp.compensated_fraction\`"
  echo "(what the traced compensation added), \`after\` is \`clamp.energy_lost_after_compensation\` (their"
  echo "difference)."
  echo
  echo "## A furnace"
  echo
  echo "A unit cube, every face a two-sided emitter of radiance 1 and reflectance 0.5, seen from its centre"
  echo "(32², 4 spp, box filter, maxdepth 2): every pixel's exact radiance is 1 + ρ + ρ² = $exact. Brute force,"
  echo "seeds ${seeds[*]}: mean ± standard deviation over the seeds of the image mean's relative error, and"
  echo "of the stats. A clamp of 0.01 is the default (c = 0.0087 here); 0.2 exaggerates it to show the"
  echo "compensation at work."
  echo
  echo "| lights | clamp | compensation samples | image mean / exact − 1 | lost | compensated |"
  echo "|---|---|---|---|---|---|"
  printf '%s\n' "${furnace_rows[@]}"
  echo
  echo "The image mean cannot show a loss of hundredths of a percent: its VPL noise is a tenth of a"
  echo "percent. The expectation can: on a render's own receivers the expected loss has a closed form"
  echo "(docs/rendering.md, \"What the compensation leaves\"), and"
  echo "\`tests/unit/test_clamp_compensation.cpp\` (\`WhatItAddsIsTheFurnacesExpectedLossInClosedForm\`: 64²,"
  echo "4 spp, 64 compensation samples, seed 5) holds what the compensation traced to it within 0.02% of the"
  echo "light. Its numbers:"
  echo
  echo "| clamp | expected loss (closed form) | compensated | left after compensation |"
  echo "|---|---|---|---|"
  printf '%s\n' "${closed_rows[@]}"
  echo
  echo "## cornell-box"
  echo
  echo "\`lightfarm render ../shared/scenes/cornell-box/scene.pbrt --method brute --resolution 128x128"
  echo "--lights 20000 --seed S --param clamp_compensation=16 --param clamp_probe=$probe_sets\`. The VPLs' own"
  echo "measure of the loss (\`lost\`) sums (1/d² − 1/c²) over the visible elements closer than c: its"
  echo "variance is unbounded (docs/rendering.md, \"What the compensation leaves\"), so it swings from seed to"
  echo "seed and \`after\` (lost − compensated) measures that swing. \`expected\` is the probe's: the same"
  echo "loss averaged over $probe_sets more light sets on the render's receivers (± its standard error over"
  echo "them), and \`left\` is expected − compensated, what the compensation leaves of the clamp's expected"
  echo "loss; \`largest set's share\` is the largest light set's part of the probe's sum (1/$probe_sets would be"
  echo "an even spread). Over the seeds, \`left\` has median **$cornell_median** and mean $cornell_mean (± standard"
  echo "error) of the light. Where one light set carries much of the probe's sum, one near-singular pair"
  echo "decided it: that seed's expectation is known only to its (large) standard error, the tail the probe"
  echo "averages over and the compensation does not have."
  echo
  echo "| seed | lost | expected | largest set's share | compensated | after | left | bound elements | render time | probe time |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
  printf '%s\n' "${cornell_rows[@]}"
  echo
  echo "## A rough mirror (scenes/glossy-plane, roughness 0.02)"
  echo
  echo "Brute force, 2000 lights, 16 spp, \`clamp_compensation=16\`, \`caustic_photons=50000\`, against"
  echo "\`path\` at 1024 spp. The split off (\`sharp_roughness=0\`: the plane's VPLs and receivers see every"
  echo "peak) and at its default (α_sharp = 0.1: the plane is sharp, its light is sampled). Region means"
  echo "over the path tracer's (1 is exact) as in docs/sharp-lobes.md; specks: backdrop pixels brighter"
  echo "than 3× the path tracer's 3×3 mean. \`bound lost\` is \`clamp.bound_lost_fraction\`."
  echo
  echo "| split | bsdf_clamp | seed | blob | backdrop | plane | specks | rel_l1 | bound elements | bound lost | compensated | time |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
  printf '%s\n' "${glossy_rows[@]}"
  echo
  echo "## veach-mis"
  echo
  echo "The default render (\`lightfarm render ../shared/scenes/veach-mis/scene.pbrt --resolution 320x180"
  echo "--param bsdf_clamp=B\`) against the truth: $truth_label."
  echo
  echo "| bsdf_clamp | method | rel_l1 | bound elements | bound lost | compensated | time |"
  echo "|---|---|---|---|---|---|---|"
  printf '%s\n' "${veach_rows[@]}"
} > "$out"
repo_relative "$out"
echo "wrote $out"
