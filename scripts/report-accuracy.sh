#!/usr/bin/env bash
# Generates docs/accuracy.md and its plots (docs/accuracy/) from `lightfarm bench` runs on the
# shared scenes, plus the surface-methods table (cornell-box and veach-mis, two
# resolutions, three light counts). Every number comes from a bench this script runs; the
# command, machine and commit are written beside it. Never edit the output by hand: re-run.
#
# Usage: scripts/report-accuracy.sh [--quick | --standard | --surface]
#   --quick     CI-sized: 32x32 and 48x48, 10^3/10^4 lights, 1 repeat (minutes)
#   --standard  256x256 and 384x384, 10^4/10^5 lights, 1 repeat, 1024 reference pixels (hours)
#   --surface   only the surface-methods table, into docs/surface-methods.md: cornell-box and
#               veach-mis at 256x256 with 10^4/10^5/10^6 lights and 384x384 with 10^4/10^5,
#               1 repeat, 1024 reference pixels (about two hours on 2 cores)
#   --media     only the media-methods table, into docs/media-methods.md: volumetric-caustic and
#               the cloud scene at 256x256 with 4000, 16000 and 64000 lights, adaptive-completion
#               (rho=0.1,sigma=0.01 with the near columns exact, and near lights sampled per row,
#               near_samples 2048 and 512) against brute force, 1 repeat, 1024 reference pixels
#               (about 90 minutes on 2 cores, references cached; LIGHTFARM_MEDIA_RESOLUTION=WxH,
#               LIGHTFARM_MEDIA_LIGHTS=N,N2 and LIGHTFARM_MEDIA_SETTINGS="rho=..,sigma=..;..."
#               override the resolution, the light counts and adaptive-completion's sweep)
#   (none)      the full report: 256x256 and 512x512, 10^4/10^5/10^6 lights, 3 repeats
# Env: LIGHTFARM_SHARED (shared data), LIGHTFARM_BUILD (build dir), LIGHTFARM_THREADS (0 = all),
#      LIGHTFARM_CACHE (reference cache root; default build/bench-cache),
#      LIGHTFARM_REPORT_ONLY=1 (rebuild the report from the previous run's bench outputs, e.g.
#      after interrupting one bench with Ctrl-C: a bench keeps the rows it finished;
#      LIGHTFARM_BENCH_COMMIT names the commit the benches were built from)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
. "$root/scripts/report-lib.sh"
shared=${LIGHTFARM_SHARED:-$(cd "$root/.." && pwd)/shared}
build=${LIGHTFARM_BUILD:-$root/build}
threads=${LIGHTFARM_THREADS:-0}
export LIGHTFARM_CACHE=${LIGHTFARM_CACHE:-$build/bench-cache}
quick=0; standard=0; surface=0; media=0
[ "${1:-}" = "--quick" ] && quick=1
[ "${1:-}" = "--standard" ] && standard=1
[ "${1:-}" = "--surface" ] && surface=1
[ "${1:-}" = "--media" ] && media=1
if [ ! -f "$build/build.ninja" ]; then bash "$root/scripts/build.sh" "$build" >/dev/null; fi
cmake --build "$build" --target lightfarm -j "$(nproc)" >/dev/null
lf="$build/lightfarm"
out="$root/docs/accuracy.md"
assets="$root/docs/accuracy"
work="$build/accuracy-runs"
if [ $surface = 1 ]; then
  out="$root/docs/surface-methods.md"; assets="$root/docs/surface-methods"; work="$build/surface-runs"
fi
if [ $media = 1 ]; then
  out="$root/docs/media-methods.md"; assets="$root/docs/media-methods"; work="$build/media-runs"
fi
report_only=${LIGHTFARM_REPORT_ONLY:-0}
[ "$report_only" = 1 ] || rm -rf "$work"
rm -rf "$assets.tmp"
mkdir -p "$work" "$assets.tmp"

# The surface table reuses the accuracy benches of cornell-box and veach-mis for its
# first resolution and adds one larger resolution.
if [ $quick = 1 ]; then
  acc_res=32x32; lights=1000,10000; repeats=1; ref_pixels=256; surf_res=48x48
elif [ $surface = 1 ]; then
  acc_res=256x256; lights=10000,100000,1000000; repeats=1; ref_pixels=1024; surf_res=384x384
  surf_lights=10000,100000
elif [ $media = 1 ]; then
  acc_res=${LIGHTFARM_MEDIA_RESOLUTION:-256x256}; lights=${LIGHTFARM_MEDIA_LIGHTS:-4000,16000,64000}
  repeats=1; ref_pixels=1024
elif [ $standard = 1 ]; then
  acc_res=256x256; lights=10000,100000; repeats=1; ref_pixels=1024; surf_res=384x384
else
  acc_res=256x256; lights=10000,100000,1000000; repeats=3; ref_pixels=4096; surf_res=512x512
fi

# The cloud scene of the media work, once it is in the tree.
scenes=(cornell-box veach-mis volumetric-caustic)
declare -A scene_file
for s in "${scenes[@]}"; do scene_file[$s]="$shared/scenes/$s/scene.pbrt"; done
for c in "$root"/scenes/*cloud*/scene.pbrt "$shared"/scenes/*cloud*/scene.pbrt; do
  [ -f "$c" ] || continue
  name=$(basename "$(dirname "$c")"); scenes+=("$name"); scene_file[$name]="$c"; break
done

skipped=()
bench() {  # tag scene-name args... : one bench into $work/tag; false if it failed
  local tag=$1 scene=$2; shift 2
  if [ "$report_only" = 1 ]; then
    [ -f "$work/$tag.log" ] && ! [ -f "$work/$tag.seconds" ] &&
      skipped+=("$tag: $(grep -v '^\s*$' "$work/$tag.log" | tr '\r' '\n' | grep -v '^\s*$' | tail -1)")
    return 0
  fi
  local cmd=("$lf" bench "${scene_file[$scene]}" --out-dir "$work/$tag" --threads "$threads" "$@")
  echo "+ ${cmd[*]}" >&2
  local t0=$SECONDS
  if ! "${cmd[@]}" 2> "$work/$tag.log"; then
    skipped+=("$tag: $(grep -v '^\s*$' "$work/$tag.log" | tail -1)")
    return 1
  fi
  echo "$((SECONDS - t0))" > "$work/$tag.seconds"
}

[ $surface = 1 ] && scenes=(cornell-box veach-mis)
media_args=()
if [ $media = 1 ]; then
  media_scenes=()
  for s in "${scenes[@]}"; do [ "$s" = volumetric-caustic ] || [[ "$s" == *cloud* ]] && media_scenes+=("$s"); done
  scenes=("${media_scenes[@]}")
  # Same-lights errors only here: the truth is measured at 32² below (a 256² path-traced truth of
  # the cloud would take hours, and volumetric-caustic's reference.exr is not its truth,
  # docs/reference-accuracy.md).
  media_args=(--methods adaptive-completion --truth none)
  # Near columns exact, then near lights sampled per row with K = 2048 and 512 draws
  # (docs/methods/adaptive-completion.md, "near lights sampled per row").
  media_settings=${LIGHTFARM_MEDIA_SETTINGS:-rho=0.1,sigma=0.01;rho=0.1,sigma=0.01,near_samples=2048;rho=0.1,sigma=0.01,near_samples=512}
  media_args+=(--settings "$media_settings")
fi
for s in "${scenes[@]}"; do
  bench "acc-$s" "$s" --resolution "$acc_res" --lights "$lights" --repeats "$repeats" \
    --reference-pixels "$ref_pixels" "${media_args[@]+"${media_args[@]}"}" || true
done
# Against the truth (the media issue's last target: time to reach 5% rel_l1 against the truth,
# adaptive-completion against brute-force VRL gathering): 32², 4 camera samples per pixel, brute
# force over every pixel, path-traced truths to 1% noise or 5 minutes (cached by the bench).
# volumetric-caustic stops at 16000 lights (its brute force at 64000 would take ~10 minutes per run).
if [ $media = 1 ]; then
  for s in "${scenes[@]}"; do
    truth_lights=${LIGHTFARM_MEDIA_TRUTH_LIGHTS:-4000,16000,64000}
    [ "$s" = volumetric-caustic ] && truth_lights=${LIGHTFARM_MEDIA_TRUTH_LIGHTS:-4000,16000}
    bench "truth-$s" "$s" --resolution "${LIGHTFARM_MEDIA_TRUTH_RESOLUTION:-32x32}" --spp 4 --lights "$truth_lights" \
      --repeats 1 --truth path --truth-noise 0.01 --truth-max-seconds 300 \
      --methods adaptive-completion --settings "$media_settings" || true
  done
fi
[ $media = 1 ] || for s in cornell-box veach-mis; do
  bench "surf-$s-$surf_res" "$s" --resolution "$surf_res" --lights "${surf_lights:-$lights}" --repeats "$repeats" \
    --reference-pixels "$ref_pixels" || true
done

commit=$(git -C "$root" rev-parse --short HEAD)$(git -C "$root" diff --quiet HEAD -- . ':!docs' || echo "+uncommitted")
machine="$(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)), $(free -g | awk '/Mem:/{print $2}') GiB"
[ "$report_only" = 1 ] && commit="$commit (report rebuilt from the bench outputs of an earlier run: the benches ran on ${LIGHTFARM_BENCH_COMMIT:+the build of }${LIGHTFARM_BENCH_COMMIT:-an earlier build})"
mode=full; [ $quick = 1 ] && mode=quick; [ $standard = 1 ] && mode=standard; [ $surface = 1 ] && mode=surface; [ $media = 1 ] && mode=media
LIGHTFARM_ACC_RES=$acc_res LIGHTFARM_ACC_LIGHTS=$lights python3 - "$work" "$assets.tmp" "$out.tmp" "$commit" "$machine" "$mode" "$(date -u +%Y-%m-%dT%H:%MZ)" \
  "${skipped[@]+"${skipped[@]}"}" <<'PY'
import csv, json, math, os, re, shutil, statistics, sys
from collections import defaultdict
work, assets, out, commit, machine, mode, date = sys.argv[1:8]
skipped = sys.argv[8:]
quick = mode == "quick"
asset_rel = os.path.basename(assets[:-4] if assets.endswith(".tmp") else assets)  # relative to docs/

def rows(tag):
    with open(os.path.join(work, tag, "results.csv")) as f:
        return list(csv.DictReader(f))

def medians(rs):
    g = defaultdict(list)
    for r in rs:
        g[(int(r["lights"]), r["method"], r["setting"].replace(" ", ","))].append(r)
    out = []
    for (l, m, s), v in g.items():
        med = lambda k: statistics.median(float(x[k]) for x in v)
        out.append(dict(lights=l, method=m, setting=s, time=med("time_total_s"),
                        rpp=med("shadow_rays_per_pixel"), rays=med("shadow_rays"), elements=med("elements"),
                        l2=med("rel_l2"), l1=med("rel_l1"), est=v[0]["estimated"] == "1",
                        ref=v[0]["reference"], w=v[0]["width"], h=v[0]["height"]))
    return out

def cmd_of(tag):
    m = re.search(r"- command: `([^`]*)`", open(os.path.join(work, tag, "report.md")).read())
    return m.group(1) if m else "?"

def secs(tag):
    p = os.path.join(work, tag + ".seconds")
    return open(p).read().strip() if os.path.exists(p) else "?"

md = []
md.append({"surface": "# Surface methods: accuracy versus time",
           "media": "# Media: adaptive-completion against brute force"}.get(mode, "# Accuracy versus time"))
md.append("")
md.append(f"Generated by `scripts/report-accuracy.sh{'' if mode == 'full' else ' --' + mode}` on {date} at commit "
          f"`{commit}` on {machine}. Every table comes from the `lightfarm bench` command printed "
          "above it (its results.csv, medians over repeats). Never edit numbers here: re-run the script.")
if quick:
    md.append("")
    md.append("**Quick mode** (CI-sized: 32² and 48² images, 10³–10⁴ lights, one repeat): shows that the "
              "pipeline works and the trends, not the numbers the targets are about. The full run is "
              "`scripts/report-accuracy.sh` (256² and 512², 10⁴–10⁶ lights, 3 repeats).")
if mode == "surface":
    md.append("")
    md.append("**Surface mode** (cornell-box and veach-mis at 256² with 10⁴–10⁶ lights "
              "and 384² with 10⁴–10⁵ lights, one repeat, errors on 1024 seeded reference pixels). The "
              "media scenes and the other plots are in [accuracy.md](accuracy.md).")
if mode == "media":
    md.append("")
    md.append(f"**Media mode** (volumetric-caustic and the cloud scene at {os.environ['LIGHTFARM_ACC_RES']} with "
              f"{' and '.join(os.environ['LIGHTFARM_ACC_LIGHTS'].split(','))} lights, adaptive-completion's ρ/σ settings against brute force with the same "
              "lights, one repeat, errors on 1024 seeded reference pixels).")
if mode == "standard":
    md.append("")
    md.append("**Standard mode** (256² and 384² images, 10⁴–10⁵ lights, one repeat, errors on 1024 "
              "seeded reference pixels): sizes up to 10⁵ lights; 10⁶ lights and 3 repeats "
              "are the full run, `scripts/report-accuracy.sh`.")
md.append("")
md.append("Errors are rel_l2 / rel_l1 against brute force with the same lights, receivers and seed. "
          "Brute force over every pixel costs lights × pixels shadow rays, so the references here are "
          "exact on a fixed, seeded random subset of pixels (`--reference-pixels`): errors are "
          "measured on those pixels, and brute force's time and rays are extrapolated from them to "
          "the whole image (marked *est.*). Time is the wall time of the whole render in one process "
          "on this shared, loaded machine.")
md.append("")
md.append("`lightfarm render|submit --target-error E` picks the cheapest setting whose median rel_l2 "
          "reached E in the scene's latest bench (`lightfarm bench` copies results.csv to "
          "`$LIGHTFARM_CACHE/bench/models/<hash of the scene files>.csv`; `--bench-dir DIR` names "
          "another), predicts its time scaled by the camera-sample count, and afterwards prints the "
          "bench's error for it and, when the bench's brute-force reference for these exact settings "
          "is cached, the measured error. Without bench results it uses these defaults: lightcuts "
          "`error=E`; mrcs `columns=12/E`, `rows=columns/2` (clamped to 50..5000); sparse-completion "
          "`rate=0.002/E` (clamped to 0.01..0.5); other methods need a bench.")
if skipped:
    md.append("")
    md.append("Interrupted or failed, so a bench may lack some of its settings (the last line of its log):")
    md.append("")
    for s in skipped:
        md.append(f"- {s}")

# --- per-scene accuracy benches -------------------------------------------------------------
for tag in sorted(t for t in os.listdir(work) if t.startswith("acc-") and os.path.isdir(os.path.join(work, t))):
    scene = tag[4:]
    if not os.path.exists(os.path.join(work, tag, "report.md")):
        continue
    dst = os.path.join(assets, scene)
    os.makedirs(dst, exist_ok=True)
    for f in ["error_vs_time.png", "error_vs_lights.png", "contact_sheet.png", "results.csv"]:
        if os.path.exists(os.path.join(work, tag, f)):
            shutil.copy(os.path.join(work, tag, f), dst)
    if os.path.isdir(os.path.join(work, tag, "heatmaps")):
        shutil.copytree(os.path.join(work, tag, "heatmaps"), os.path.join(dst, "heatmaps"))
    text = open(os.path.join(work, tag, "report.md")).read()
    text = re.sub(r"^(#+) lightfarm bench: .*$", f"## {scene}", text, count=1, flags=re.M)
    if mode == "media":  # the truth is measured by the truth-* benches (see "Against the truth")
        text = re.sub(r"\n## Against the truth\n.*?(?=\n## |\Z)", "\n", text, flags=re.S)
    text = re.sub(r"^## ", "### ", text[text.index("\n"):], flags=re.M)
    text = re.sub(r"\]\(((?!http)[^)]+)\)", lambda m: f"]({asset_rel}/{scene}/{m.group(1)})", text)
    md.append("")
    md.append(f"## {scene}")
    md.append(f"\n({secs(tag)} s for the whole bench; raw rows: [results.csv]({asset_rel}/{scene}/results.csv))")
    md.append(text)

# --- media methods ---------------------------------------------------------------------------
if mode == "media":
    md.append("")
    md.append("## Targets")
    md.append("")
    md.append("Target 1: at ≤ 2% rel_l1, adaptive-completion ≥ 20× faster than brute force at 16000 lights "
              "and ≥ 40× at 64000 (same lights; brute force's time extrapolated from its reference pixels, "
              "*est.*; smaller light counts are shown without a target). Target 2: at 4× the lights, the "
              "same setting takes ≤ 2× the time and evaluates ≤ 2× the elements. Target 3: per evaluated "
              "element, ≤ 1.2× brute force's cost (whole-render time over elements evaluated, both from "
              "the same bench).")
    md.append("")
    md.append("| scene | lights | fastest setting at ≤ 2% rel_l1 | time vs brute | speedup | elements evaluated | target | met |")
    md.append("|---|---|---|---|---|---|---|---|")
    scaling_rows = []
    cost_rows = []
    def speed_target(L):
        return 40 if L >= 64000 else (20 if L >= 16000 else None)
    for tag in sorted(t for t in os.listdir(work) if t.startswith("acc-") and os.path.exists(os.path.join(work, t, "results.csv"))):
        raw = rows(tag)
        ms = medians(raw)
        frac = defaultdict(list)
        for r in raw:
            frac[(int(r["lights"]), r["method"], r["setting"].replace(" ", ","))].append(float(r["fraction_evaluated"]))
        counts = sorted({m["lights"] for m in ms})
        for L in counts:
            b = [m for m in ms if m["method"] == "brute" and m["lights"] == L]
            ok = [m for m in ms if m["method"] != "brute" and m["lights"] == L and m["l1"] <= 0.02]
            if not b:
                continue
            if not ok:
                best = min((m for m in ms if m["method"] != "brute" and m["lights"] == L), key=lambda m: m["l1"], default=None)
                note = f"none (best rel_l1 {best['l1']:.4f} at `{best['setting']}`, {best['time']:.3g} s)" if best else "none"
                tg = speed_target(L)
                md.append(f"| {tag[4:]} | {L} | {note} | — | — | — | {f'{tg}×' if tg else '—'} | {'no' if tg else '—'} |")
                continue
            f = min(ok, key=lambda m: m["time"])
            sp = b[0]["time"] / f["time"]
            fr = statistics.median(frac[(L, f["method"], f["setting"])])
            tg = speed_target(L)
            md.append(f"| {tag[4:]} | {L} | {f['method']} `{f['setting']}` (rel_l1 {f['l1']:.4f}) | {f['time']:.3g} s vs "
                      f"{b[0]['time']:.3g} s{' *est.*' if b[0]['est'] else ''} | {sp:.1f}× | {fr:.2%} | "
                      f"{f'{tg}×' if tg else '—'} | {('yes' if sp >= tg else 'no') if tg else '—'} |")
        for L in counts:
            b = [m for m in ms if m["method"] == "brute" and m["lights"] == L]
            if not b or not b[0]["elements"] > 0:
                continue
            brute_us = b[0]["time"] / b[0]["elements"] * 1e6
            for m in ms:
                if m["method"] == "brute" or m["lights"] != L or not m["elements"] > 0:
                    continue
                us = m["time"] / m["elements"] * 1e6
                cost_rows.append(f"| {tag[4:]} | {L} | {m['method']} `{m['setting']}` | {us:.3g} µs | {brute_us:.3g} µs"
                                 f"{' *est.*' if b[0]['est'] else ''} | {us / brute_us:.2f}× | {'yes' if us <= 1.2 * brute_us else 'no'} |")
        # Each step between consecutive light counts (4× in the default run): the time ratio and
        # the elements' ratio (which the machine's load does not move), against the target's
        # 2× per 4× (a power law of exponent 0.5; other steps are scaled to it).
        for lo, hi in zip(counts, counts[1:]):
            allowed = (hi / lo) ** 0.5
            for m in ms:
                if m["method"] == "brute" or m["lights"] != lo:
                    continue
                h = [x for x in ms if x["method"] == m["method"] and x["setting"] == m["setting"] and x["lights"] == hi]
                if h and m["time"] > 0:
                    r = h[0]["time"] / m["time"]
                    e_lo = statistics.median(frac[(lo, m["method"], m["setting"])]) * lo
                    e_hi = statistics.median(frac[(hi, m["method"], m["setting"])]) * hi
                    scaling_rows.append(f"| {tag[4:]} | {m['method']} `{m['setting']}` | {lo}→{hi} | "
                                        f"{m['time']:.3g} s → {h[0]['time']:.3g} s | {r:.2f}× | {e_hi / e_lo:.2f}× | "
                                        f"{allowed:.2f}× | {'yes' if r <= allowed and e_hi / e_lo <= allowed else 'no'} |")
    md.append("")
    md.append("| scene | setting | lights | time | time ratio | elements ratio | allowed | met |")
    md.append("|---|---|---|---|---|---|---|---|")
    md.extend(scaling_rows)
    md.append("")
    md.append("| scene | lights | setting | time per element | brute force's | ratio | met (≤ 1.2×) |")
    md.append("|---|---|---|---|---|---|---|")
    md.extend(cost_rows)

    # Target 4: against the truth, time to reach 5% rel_l1 (and the looser levels, which show how
    # far both are from it), adaptive-completion against brute-force gathering with its own lights.
    md.append("")
    md.append("Target 4: against the truth, adaptive-completion reaches 5% rel_l1 ≥ 10× sooner than brute-force "
              "VRL gathering. Both are swept over the light count (brute force) and the light count and setting "
              "(adaptive-completion); the fastest run at or below each level wins. 10% and 20% show how far both "
              "are from 5%.")
    truth_tags = sorted(t for t in os.listdir(work) if t.startswith("truth-") and os.path.exists(os.path.join(work, t, "results.csv")))
    floor_lines = []
    if truth_tags:
        md.append("")
        md.append("| scene | truth rel_l1 | brute force: fastest run | adaptive-completion: fastest run | ratio | met (≥ 10×) |")
        md.append("|---|---|---|---|---|---|")
    for tag in truth_tags:
        raw = rows(tag)
        g = defaultdict(list)
        for r in raw:
            g[(int(r["lights"]), r["method"], r["setting"].replace(" ", ","))].append(r)
        runs = []
        for (L, m, st), v in g.items():
            t1 = [float(x["truth_rel_l1"]) for x in v if x["truth_rel_l1"] not in ("", "nan")]
            if t1:
                runs.append(dict(lights=L, method=m, setting=st, time=statistics.median(float(x["time_total_s"]) for x in v),
                                 t1=statistics.median(t1)))
        tj = {}
        try:
            tj = json.load(open(os.path.join(work, tag, "truth.json")))
        except Exception:
            pass
        noise = tj.get("noise_rel_l1")
        for level in (0.2, 0.1, 0.05):
            def fastest(method_is_brute):
                c = [x for x in runs if (x["method"] == "brute") == method_is_brute and x["t1"] <= level]
                return min(c, key=lambda x: x["time"]) if c else None
            b, a = fastest(True), fastest(False)
            bs = f"{b['time']:.3g} s ({b['lights']} lights, {b['t1']:.3f})" if b else "—"
            as_ = f"{a['time']:.3g} s ({a['lights']} lights, `{a['setting']}`, {a['t1']:.3f})" if a else "—"
            ratio = f"{b['time'] / a['time']:.1f}×" if (a and b) else "—"
            met = ("yes" if b["time"] / a["time"] >= 10 else "no") if (a and b) else ("no" if level == 0.05 else "—")
            md.append(f"| {tag[6:]} | {level:.0%} | {bs} | {as_} | {ratio} | {met if level == 0.05 else '—'} |")
        brute = sorted((x for x in runs if x["method"] == "brute"), key=lambda x: x["lights"])
        if brute:
            floor_lines.append(f"- {tag[6:]} ({raw[0]['width']}x{raw[0]['height']}, {raw[0]['spp']} spp; `{cmd_of(tag)}`): brute force's "
                               "own truth rel_l1 " + ", ".join(f"{x['t1']:.3f} at {x['lights']} lights ({x['time']:.3g} s)" for x in brute)
                               + (f"; the truth's own noise rel_l1 {noise:.3f} ({tj.get('label', '')})" if isinstance(noise, (int, float)) else ""))
    if floor_lines:
        md.append("")
        md.append("Brute force with every light is the floor of every many-light method against the truth:")
        md.append("")
        md.extend(floor_lines)

    # Why the sampled near lights stop short of target 1: at the largest light count, the error of
    # near_samples=512 and 2048 gives the rate at which it falls with K, and the two times the cost
    # of a draw; both extrapolated to the K that would reach 2%.
    why = []
    for tag in sorted(t for t in os.listdir(work) if t.startswith("acc-") and os.path.exists(os.path.join(work, t, "results.csv"))):
        ms = medians(rows(tag))
        if not ms:
            continue
        L = max(m["lights"] for m in ms)
        at = {m["setting"]: m for m in ms if m["lights"] == L}
        b = next((m for m in ms if m["method"] == "brute" and m["lights"] == L), None)
        k_runs = sorted(((int(re.search(r"near_samples=(\d+)", st).group(1)), m) for st, m in at.items()
                         if m["method"] != "brute" and re.search(r"near_samples=(\d+)", st)), key=lambda x: x[0])
        if not b or len(k_runs) < 2:
            continue
        (k0, m0), (k1, m1) = k_runs[0], k_runs[-1]
        if not (m0["l1"] > m1["l1"] > 0) or k1 <= k0:
            why.append(f"- {tag[4:]}, {L} lights: rel_l1 {m0['l1']:.4f} at K = {k0} and {m1['l1']:.4f} at K = {k1}: "
                       "more draws did not lower the error, so no extrapolation.")
            continue
        slope = math.log(m0["l1"] / m1["l1"]) / math.log(k1 / k0)
        per_draw = (m1["time"] - m0["time"]) / (k1 - k0)
        line = (f"- {tag[4:]}, {L} lights: with the near lights sampled per row, rel_l1 falls as K^−{slope:.2f} "
                f"({m0['l1']:.4f} at K = {k0}, {m1['l1']:.4f} at K = {k1}; 1/√K would be K^−0.50)")
        if m1["l1"] > 0.02 and per_draw > 0:
            k2 = k1 * (m1["l1"] / 0.02) ** (1 / slope)
            t2 = m1["time"] + per_draw * (k2 - k1)
            line += (f"; 2% would take K ≈ {k2:.0f} draws per row, about {t2:.3g} s at the measured "
                     f"{per_draw * 1e3:.3g} ms per unit of K: {b['time'] / t2:.1f}× brute force.")
        else:
            line += f"; K = {k1} is at or below 2% in {m1['time']:.3g} s ({b['time'] / m1['time']:.1f}× brute force)."
        ex = at.get("rho=0.1,sigma=0.01")
        if ex:
            line += (f" With the near columns exact, {ex['l1']:.4f} in {ex['time']:.3g} s ({b['time'] / ex['time']:.1f}× brute force), "
                     "and its elements grow with the lights (the scaling table).")
        why.append(line)
    if why:
        md.append("")
        md.append("## Why the targets are not met")
        md.append("")
        md.append("From the benches above (the near lights' sampling error and cost, extrapolated; a model, not a measurement):")
        md.append("")
        md.extend(why)
        md.append("")
        md.append("What was tried, with its numbers and the reason each was kept or rejected: "
                  "[methods/adaptive-completion.md](methods/adaptive-completion.md) (near columns and the cheaper "
                  "splits, a smooth part and a near-pair remainder, near lights sampled per row and their densities, "
                  "pilot rows, the VRLs' emitted share, near lights drawn through the light tree, where the time goes).")
    open(out, "w").write("\n".join(md) + "\n")
    sys.exit(0)

# --- surface methods ---------------------------------------------------------------
md.append("")
md.append("## Surface methods")
md.append("")
md.append("cornell-box and veach-mis at two resolutions and three light counts: for each method "
          "and budget, time, shadow rays per pixel and error against brute force with the same lights.")
surf = sorted(t for t in os.listdir(work) if (t.startswith("surf-") or t in ("acc-cornell-box", "acc-veach-mis"))
              and os.path.exists(os.path.join(work, t, "results.csv")))
targets = []
scaling = []
for tag in surf:
    ms = medians(rows(tag))
    md.append("")
    label = tag.split("-", 1)[1] if tag.startswith("surf-") else f"{tag[4:]}-{rows(tag)[0]['width']}x{rows(tag)[0]['height']}"
    md.append(f"### {label}")
    md.append("")
    md.append(f"`{cmd_of(tag)}` ({secs(tag)} s)")
    md.append("")
    md.append("| lights | method | budget | time | shadow rays / pixel | rel_l2 | rel_l1 |")
    md.append("|---|---|---|---|---|---|---|")
    for m in ms:
        md.append(f"| {m['lights']} | {m['method']} | `{m['setting']}` | {m['time']:.3g} s{' *est.*' if m['est'] else ''} | "
                  f"{m['rpp']:.1f}{' *est.*' if m['est'] else ''} | {m['l2']:.4f} | {m['l1']:.4f} |")
    # Targets at 10^5 lights (or the largest count run).
    counts = sorted({m["lights"] for m in ms})
    L = min(counts, key=lambda c: abs(math.log(c / 1e5)))  # counts are actual: 100003, not 10^5
    brute = [m for m in ms if m["method"] == "brute" and m["lights"] == L]
    if not brute:
        continue
    b = brute[0]
    def min_rays(method, err):
        c = [m["rpp"] for m in ms if m["method"] == method and m["lights"] == L and m["l2"] <= err]
        return min(c) if c else None
    for method in sorted({m["method"] for m in ms} - {"brute"}):
        r = min_rays(method, 0.02)
        if r is None:
            targets.append(f"| {label} | {L} | {method} | — (no budget reached 2%) | no |")
        else:
            ratio = b["rpp"] / r
            targets.append(f"| {label} | {L} | {method} | {r:.1f} vs brute {b['rpp']:.0f}: {ratio:.1f}× fewer | "
                           f"{'yes' if ratio >= 30 else 'no'} |")
    # Time against light count for each method's settings present at every count: the exponent
    # of a power law through the smallest and largest count (1 = linear).
    if len(counts) > 1:
        lo, hi = counts[0], counts[-1]
        for method in sorted({m["method"] for m in ms} - {"brute"}):
            exps = []
            for m in ms:
                if m["method"] != method or m["lights"] != lo:
                    continue
                h = [x for x in ms if x["method"] == method and x["setting"] == m["setting"] and x["lights"] == hi]
                if h and m["time"] > 0 and h[0]["time"] > 0:
                    exps.append(math.log(h[0]["time"] / m["time"]) / math.log(hi / lo))
            if exps:
                e = statistics.median(exps)
                scaling.append(f"| {label} | {method} | {lo}→{hi} | {e:.2f} (settings: {len(exps)}, "
                               f"range {min(exps):.2f}..{max(exps):.2f}) | {'yes' if e < 1 else 'no'} |")
    methods = {m["method"] for m in ms}
    if "sparse-completion" in methods and "lightslice" in methods:
        for err in (0.01, 0.02, 0.03, 0.05, 0.1):
            s, l = min_rays("sparse-completion", err), min_rays("lightslice", err)
            if s is not None and l is not None:
                targets.append(f"| {label} | {L} | sparse-completion vs lightslice at {err:.0%} | "
                               f"{s:.1f} vs {l:.1f} rays/pixel | {'yes' if s <= l / 2 else 'no'} |")
                break
md.append("")
md.append("### Targets")
md.append("")
md.append("Target 1: at ≤ 2% rel_l2, ≥ 30× fewer shadow rays than brute force at 10⁵ lights "
          "(quick mode: at its largest light count, 10⁴). Target 2: sparse-completion needs ≤ ½ the "
          "rays of lightslice at equal error (the smallest error both reach)"
          + ("" if any("lightslice" in t for t in targets) else
             "; not measurable in this tree: `lightslice` is not registered yet") + ".")
md.append("")
md.append("| bench | lights | method | fewest rays/pixel at ≤ 2% | met |")
md.append("|---|---|---|---|---|")
md.extend(targets)
md.append("")
md.append("Target 3: time grows sublinearly with the number of lights. Median over a method's settings "
          "of the exponent e in time ∝ lights^e between the smallest and largest light count "
          "(the whole render's wall time, light generation and tree building included).")
md.append("")
md.append("| bench | method | lights | exponent e | sublinear |")
md.append("|---|---|---|---|---|")
md.extend(scaling)
open(out, "w").write("\n".join(md) + "\n")
PY
rm -rf "$assets"
mv "$assets.tmp" "$assets"
repo_relative "$out.tmp"
mv "$out.tmp" "$out"
echo "wrote $out and $assets/" >&2
