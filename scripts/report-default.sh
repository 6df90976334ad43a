#!/usr/bin/env bash
# Generates docs/default-vs-path.md: what a user gets from `lightfarm render SCENE` with no
# options (method auto, the scene's Film resolution, 10000 lights) against the path tracer given
# the same time, on every shared scene, both measured against the truth. Every number comes from
# a command this script runs; never edit the output.
#
# The path tracer's equal-time run: `path` at 1 and 16 spp gives its fixed cost and its cost per
# sample; the spp that fills the default render's time is rendered (once more, rescaled, when it
# missed that time by more than 10%) and its actual time reported.
# Truth: the scene's reference.exr (area-averaged when its resolution differs), except where that
# image does not show what the file describes (veach-mis, volumetric-caustic:
# docs/reference-accuracy.md) or where there is none (the project's scenes); there `path` renders
# progressively until its noise is below 1% or LIGHTFARM_TRUTH_SECONDS (default 600) pass, and
# the table states the noise it reached.
#
# Usage: scripts/report-default.sh [--method M] [--resolution WxH[,WxH...]] [--out FILE] [SCENE_NAME...]
#   SCENE_NAME: a directory under $LIGHTFARM_SHARED/scenes, else under scenes/ here (default: every
#   shared scene and scenes/product-shot). --method renders M instead of auto (the question "would M beat path here?");
#   --resolution renders every scene at each size instead of its Film's; --out writes the table
#   there instead of docs/default-vs-path.md. The media comparison in docs/media-vs-path.md:
#   scripts/report-default.sh --method adaptive-completion --resolution 128x128,256x256 \
#       --out docs/media-vs-path.md volumetric-caustic cloud
# LIGHTFARM_REUSE_RUNS=1 keeps the renders a previous run left in build/default-runs*/ and only
# measures and writes the table again; a truth.exr left there is always reused.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
shared=${LIGHTFARM_SHARED:-$(cd "$root/.." && pwd)/shared}
build=${LIGHTFARM_BUILD:-$root/build}
bash "$root/scripts/build.sh" "$build" >/dev/null
lf="$build/lightfarm"
runs="$build/default-runs"
truth_s=${LIGHTFARM_TRUTH_SECONDS:-600}
method_arg=()
resolutions=("")
out="$root/docs/default-vs-path.md"
scenes=()
while [ $# -gt 0 ]; do
  case "$1" in
    --method) method_arg=(--method "$2"); shift 2 ;;
    --resolution) IFS=, read -r -a resolutions <<<"$2"; shift 2 ;;
    --out) out=$2; shift 2 ;;
    -*) echo "report-default: unknown option $1" >&2; exit 2 ;;
    *) scenes+=("$1"); shift ;;
  esac
done
if [ ${#scenes[@]} -eq 0 ]; then
  for d in "$shared"/scenes/*/; do scenes+=("$(basename "$d")"); done
  # The project's own product shot (coats, glass, polished metal: docs/rendering.md, "Split vertices").
  scenes+=(product-shot)
fi
invocation="scripts/report-default.sh${method_arg[*]:+ ${method_arg[*]}}"
[ -n "${resolutions[0]}" ] && invocation+=" --resolution $(IFS=,; echo "${resolutions[*]}")"
[ "$out" != "$root/docs/default-vs-path.md" ] && invocation+=" --out ${out#"$root"/}"
invocation+=" ${scenes[*]}"

# Renders unless LIGHTFARM_REUSE_RUNS=1 and the run's stats exist (the last argument pair is
# --stats FILE).
render() {
  local stats="${*: -1}"
  rendered=0
  if [ "${LIGHTFARM_REUSE_RUNS:-0}" = 1 ] && [ -f "$stats" ]; then return 0; fi
  "$lf" render "$@"
  rendered=1
}
# `path` with N samples per pixel: above the 4096 one render allows, in equal passes (their
# images averaged: the same estimator), with the time of all of them.
path_args() {
  local n=$1 passes=$(( ($1 + 4095) / 4096 ))
  echo --spp $(( (n + passes - 1) / passes )) --passes "$passes"
}
json() { /usr/bin/python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print(eval(sys.argv[2], {'d': d}))" "$@"; }
error() { "$lf" compare --resize --json "$1" "$2" | /usr/bin/python3 -c "import json,sys; d=json.load(sys.stdin); print(d['rel_l1'], d['rel_l2'], f\"{d['speck_share']}:{d['dark_specks'] + d['bright_specks']}\")"; }

rows=()
for name in "${scenes[@]}"; do
for res in "${resolutions[@]}"; do
  scene="$shared/scenes/$name/scene.pbrt"
  [ -f "$scene" ] || scene="$root/scenes/$name/scene.pbrt"
  [ -f "$scene" ] || { echo "report-default: no scene $name in $shared/scenes or $root/scenes" >&2; exit 2; }
  size=()
  [ -n "$res" ] && size=(--resolution "$res")
  w="$runs/$name${res:+-$res}"
  mkdir -p "$w"
  echo "default-vs-path: $name ${res:-(Film resolution)}" >&2
  render "$scene" --quiet "${method_arg[@]}" "${size[@]}" --out "$w/default.exr" --stats "$w/default.json"
  t_default=$(json "$w/default.json" "d['time']['total_s']")
  method=$(json "$w/default.json" "d['method']")
  rule=$(json "$w/default.json" "d.get('method_rule', '')")
  lights=$(json "$w/default.json" "d['lights']['total']")
  spp=$(json "$w/default.json" "d['spp']")

  reference="$(dirname "$scene")/reference.exr"
  case "$name" in veach-mis|volumetric-caustic) reference= ;; esac
  if [ -n "$reference" ] && [ -f "$reference" ]; then
    truth="$reference"
    truth_label="reference.exr"
  else
    if [ ! -f "$w/truth.exr" ]; then
      "$lf" render "$scene" --quiet "${size[@]}" --method path --seed 7 --until-noise 0.01 --time-limit "$truth_s" \
        --out "$w/truth.exr" --stats "$w/truth.json"
    fi
    truth="$w/truth.exr"
    truth_label=$(json "$w/truth.json" "'path-traced here (\`--method path\`, progressive): %d passes x %d spp in %.0f s; relative standard error of its image mean %.4f, of its 90th-percentile pixel %.3f' % (d['passes'], d['spp'], sum(d['pass_times_s']), d['noise']['rel_stderr'], d['noise']['p90_rel_stderr'])")
  fi
  read -r e_default e2_default sp_default < <(error "$truth" "$w/default.exr")

  # Path's cost model from 1 and 16 spp (at 1 and 4 a small image's difference was within the
  # timer's noise: the cloud at 128² once measured 4 spp faster than 1 and asked for 65536 spp),
  # then its equal-time run.
  render "$scene" --quiet "${size[@]}" --method path --spp 1 --seed 3 --out "$w/path1.exr" --stats "$w/path1.json"
  render "$scene" --quiet "${size[@]}" --method path --spp 16 --seed 3 --out "$w/path16.exr" --stats "$w/path16.json"
  t1=$(json "$w/path1.json" "d['time']['total_s']")
  t16=$(json "$w/path16.json" "d['time']['total_s']")
  path_spp=$(/usr/bin/python3 -c "
per = max(($t16 - $t1) / 15, 1e-6); fixed = max($t1 - per, 0)
print(max(1, min(65536, int(($t_default - fixed) / per))))")
  render "$scene" --quiet "${size[@]}" --method path $(path_args "$path_spp") --seed 3 --out "$w/path.exr" --stats "$w/path.json"
  t_path=$(json "$w/path.json" "d['time']['total_s']")
  path_spp=$(json "$w/path.json" "d['spp'] * d.get('passes', 1)")
  # The model is linear; when the run missed the default's time by more than 10%, the spp is
  # rescaled by the measured ratio and rendered once more.
  rescaled=$(/usr/bin/python3 -c "
r = $t_default / max($t_path, 1e-6)
print(max(1, min(65536, round($path_spp * r))) if abs(r - 1) > 0.1 else 0)")
  if [ "$rescaled" -gt 0 ] && [ "$rendered" = 1 ]; then
    path_spp=$rescaled
    "$lf" render "$scene" --quiet "${size[@]}" --method path $(path_args "$path_spp") --seed 3 --out "$w/path.exr" --stats "$w/path.json"
    t_path=$(json "$w/path.json" "d['time']['total_s']")
    path_spp=$(json "$w/path.json" "d['spp'] * d.get('passes', 1)")
  fi
  read -r e_path e2_path sp_path < <(error "$truth" "$w/path.exr")
  # The camera-side supersampling's share: active pixels and the receivers phase (pilot and
  # camera paths included) against the whole render.
  camera=$(json "$w/default.json" "'active in %d of %d pixels; the receivers phase, pilot and camera paths included, took %.1f s' % (d['receivers'].get('camera_active_pixels', 0), d['resolution'][0] * d['resolution'][1], d['time']['phases'].get('receivers', 0))")
  shown_res=$(json "$w/default.json" "'%dx%d' % tuple(d['resolution'])")
  rows+=("$name|$shown_res|$method|$rule|$lights|$spp|$t_default|$e_default|$e2_default|$sp_default|$path_spp|$t_path|$e_path|$e2_path|$sp_path|$truth_label|$camera")
done
done

printf '%s\n' "${rows[@]}" >"$runs/rows.txt"
/usr/bin/python3 - "$out" "$(git -C "$root" rev-parse --short HEAD)$(git -C "$root" diff --quiet || echo +uncommitted)" "$(nproc)" "$runs/rows.txt" "$invocation" "${method_arg[1]:-}" "${resolutions[*]}" <<'EOF'
import sys, datetime
out, commit, cores, rows, invocation, forced, sizes = sys.argv[1:8]
lines = [l.split("|") for l in open(rows).read().splitlines() if l]
what = (f"`lightfarm render SCENE --method {forced}`" if forced else "What a user gets from `lightfarm render SCENE` with no options (method `auto`")
size = (f"at {', '.join(sizes.split())} (`--resolution`)" if sizes.strip() else "the scene's Film resolution")
md = ["# The default render against the path tracer at equal time" if not forced else
      f"# `{forced}` against the path tracer at equal time", "",
      f"Generated by `{invocation.strip()}` on {datetime.datetime.utcnow():%Y-%m-%dT%H:%MZ} at commit `{commit}` "
      f"on {cores} cores. Never edit the numbers: re-run the script.", "",
      (f"{what} with its defaults otherwise ({size}, 10000 lights; " if forced else f"{what}, {size}, 10000 lights; ") +
      "for the many-light methods 1 receiver per pixel, plus camera paths for the light "
      "camera paths find by themselves where a pilot sees it vary, 256 per such pixel on average, "
      "shared in proportion to how much it varies: "
      "docs/rendering.md, camera-side supersampling), against `path` "
      "given the same time. The path tracer's samples per pixel fill the default render's time "
      "(its cost from 1 and 16 spp), and its actual time is shown. Both are measured against the truth: "
      "`rel_l1` = ‖truth − image‖₁ / ‖truth‖₁ and `rel_l2` over all pixel channels. `ratio` is path's " +
      ("rel_l1 over the default's: above 1 the default is closer to the truth at equal time." if not forced else
       f"rel_l1 over `{forced}`'s: above 1 `{forced}` is closer to the truth at equal time."), "",
      "| scene | resolution | default: method (auto's rule) | lights | time | rel_l1 | rel_l2 | specks | path spp | path time | path rel_l1 | path rel_l2 | path specks | ratio | verdict |",
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
if forced:
    md[-2] = md[-2].replace("default: method (auto's rule)", "method")
notes = []
def specks(field):  # "share:count" -> "0.34% (108)"
    share, count = field.split(":")
    return f"{100 * float(share):.2f}% ({count})"
for (name, res, method, rule, lights, spp, t, e, e2, sp, pspp, tp, ep, ep2, psp, truth, camera) in lines:
    ratio = float(ep) / max(float(e), 1e-12)
    verdict = (f"{method} wins" if forced else "default wins") if ratio > 1.1 else ("path wins" if ratio < 1 / 1.1 else "level")
    md.append(f"| {name} | {res} | {method}{f' ({rule})' if rule else ''} | {lights} | {float(t):.1f} s | {float(e):.4f} | {float(e2):.4f} | {specks(sp)} | "
              f"{pspp} | {float(tp):.1f} s | {float(ep):.4f} | {float(ep2):.4f} | {specks(psp)} | {ratio:.2f} | {verdict} |")
    notes.append(f"- {name}, {res}: truth {truth}." + (f" Camera-side supersampling: {camera}."
                                                 if method != "path" else ""))
    if method == "path" and not forced:
        notes.append(f"  The default is `path` here ({rule}): in media without caustics no many-light method "
                     "was closer to the truth at equal time (docs/methods/media-elements.md; docs/rendering.md, `auto`), so both columns are "
                     "the path tracer and differ only by seed and spp.")
md += ["", "`level`: within 10%. The verdict is on rel_l1; rel_l2 weighs the brightest pixels most "
       "(a visible light's edges and highlights), so read both. `specks`: the share (and count) of lit truth pixels "
       "the image has below 0.3x the smallest or above 3x the largest truth value in their 3x3 neighbourhood "
       "(single-pixel black or bright dots; the truth's own edges never count; `lightfarm compare`). Truths:", ""] + notes + ["",
       "A path-traced truth carries its own noise (stated above): per pixel it is far above the image mean's, "
       "and it adds to both columns' errors alike. "
       "Times are wall times of the whole render in one process on this shared machine, one run each. "
       "The path tracer renders with a fixed seed (3); the truth with another (7)."]
open(out, "w").write("\n".join(md) + "\n")
print("\n".join(md))
EOF
