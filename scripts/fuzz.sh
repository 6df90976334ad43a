#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/, clang, ASan + UBSan) in build-fuzz/ and runs each for a
# bounded time on a seed corpus made from the shared scenes, the project's scenes and generated
# farm messages. Fails when a target crashes, leaks or times out; the input that did it is kept
# in build-fuzz/artifacts/TARGET/ (check it in under fuzz/regressions/TARGET/ with a test).
# Usage: scripts/fuzz.sh [seconds-per-target]   (default 60)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seconds=${1:-60}
build=${LIGHTFARM_FUZZ_BUILD:-$root/build-fuzz}
shared=${LIGHTFARM_SHARED:-$(cd "$root/.." && pwd)/shared}
targets=(parse_scene read_ply decode_farm)

bash "$root/scripts/install-deps.sh"
if [ ! -f "$build/build.ninja" ]; then
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DLIGHTFARM_FUZZ=ON -DLIGHTFARM_WERROR=OFF >/dev/null
fi
start=$(date +%s)
cmake --build "$build" --parallel "$(nproc)" --target fuzz_make_seeds \
  $(printf 'fuzz_%s ' "${targets[@]}")
echo "fuzz: build took $(( $(date +%s) - start )) s"

# Seed corpus (read-only inputs); new inputs the fuzzer finds go to corpus/TARGET.
seeds=$build/seeds
rm -rf "$seeds"
mkdir -p "$seeds/parse_scene" "$seeds/read_ply" "$seeds/decode_farm"
ASAN_OPTIONS=detect_leaks=0 "$build/fuzz/fuzz_make_seeds" "$seeds"
n=0
while IFS= read -r -d '' f; do
  cp "$f" "$seeds/parse_scene/seed$((n++)).pbrt"
done < <(find "$shared/scenes" "$root/scenes" -name '*.pbrt' -print0 2>/dev/null)
# Large meshes make every execution slow without covering more of the reader.
while IFS= read -r -d '' f; do
  cp "$f" "$seeds/read_ply/seed$((n++)).ply"
done < <(find "$shared/scenes" "$root/scenes" -name '*.ply' -size -64k -print0 2>/dev/null)
[ -d "$shared/scenes" ] || echo "fuzz: warning: no shared scenes at $shared (seeds from scenes/ only)" >&2

failed=()
for t in "${targets[@]}"; do
  corpus=$build/corpus/$t
  artifacts=$build/artifacts/$t
  mkdir -p "$corpus" "$artifacts"
  regressions=()
  [ -d "$root/fuzz/regressions/$t" ] && regressions=("$root/fuzz/regressions/$t")
  log=$build/$t.log
  echo "fuzz: $t for ${seconds} s"
  # -timeout: one input taking longer is a hang (generous: a loaded CI machine can stall a
  # process for seconds; every seed runs in milliseconds); -rss_limit_mb: an input that makes the code
  # allocate gigabytes is a bug too (the readers bound allocations by the input's size).
  if ASAN_OPTIONS=halt_on_error=1:detect_leaks=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
     "$build/fuzz/fuzz_$t" "$corpus" "$seeds/$t" "${regressions[@]}" \
       -max_total_time="$seconds" -timeout=60 -rss_limit_mb=2048 -max_len=65536 \
       -artifact_prefix="$artifacts/" -print_final_stats=1 >"$log" 2>&1; then
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
    rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
    echo "fuzz: $t ok: $execs executions, $rate exec/s, corpus $(ls "$corpus" | wc -l) inputs"
  else
    echo "fuzz: $t FAILED; log $log, inputs in $artifacts:" >&2
    grep -E "ERROR|SUMMARY|runtime error|Test unit written" "$log" | head -20 >&2 || true
    failed+=("$t")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: failures in ${failed[*]}" >&2
  exit 1
fi
echo "fuzz: all targets ran ${seconds} s without a failure"
