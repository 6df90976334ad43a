#!/usr/bin/env bash
# Builds lightfarm with AddressSanitizer + UndefinedBehaviorSanitizer (LIGHTFARM_SANITIZE) in its
# own tree, build-asan/, and runs the unit and stability suites there. Any sanitizer report fails
# the test that triggered it (halt_on_error), leaks included; the `lightfarm` binary the CLI
# tests run is instrumented too.
# Usage: scripts/sanitize.sh [extra ctest args...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${LIGHTFARM_ASAN_BUILD:-$root/build-asan}
bash "$root/scripts/install-deps.sh"
# No -Werror here: the Release build gates warnings on the same sources, and ASan's
# instrumentation makes GCC 12's flow analysis report false -Wmaybe-uninitialized positives in
# libstdc++ (std::regex's NFA, seen on cli/render_options.cpp).
werror=OFF
if [ ! -f "$build/build.ninja" ]; then
  # -O1: close to the optimised code the bugs live in, at half the compile time of -O2 -g.
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DLIGHTFARM_SANITIZE=ON \
    -DLIGHTFARM_WERROR=$werror >/dev/null
fi
start=$(date +%s)
cmake --build "$build" --parallel "$(nproc)" \
  --target lightfarm lightfarm_unit_tests lightfarm_unit_shared_tests lightfarm_stability_tests
echo "sanitize: build took $(( $(date +%s) - start )) s"

export LIGHTFARM_SHARED=${LIGHTFARM_SHARED:-$(cd "$root/.." && pwd)/shared}
export ASAN_OPTIONS=halt_on_error=1:detect_leaks=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=0
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
export LSAN_OPTIONS=suppressions=$root/scripts/lsan.supp
start=$(date +%s)
cd "$build"
# The statistical convergence tests (an estimator against the path tracer or brute force at
# thousands of samples, 10-40 s each in the Release build, 4-5x that here) run the code paths
# the smaller tests of the same files already run; sanitizers find memory and UB errors, which do
# not need the extra samples. They run once, in the README's suite.
convergence='^(MediaPieces\.CutRowsPiecesAndCameraSideDirectLightGiveTheSameImage|Caustics\.BeamThroughFogMatchesThePathTracer|ClampCompensation\.TheElementBoundTakesGlossyPeaksAndTheCompensationGivesThemBack|AdaptiveCompletion\.(FullSamplingEqualsBruteForceInMedia|NearLightsSampledPerRowAreUnbiasedAndConverge)|PassAccumulator\.NoiseEstimateMatchesTheSpreadOfIndependentJobs|Bench\.ErrorDecreasesAsTheBudgetGrows)$'
ctest --output-on-failure --timeout 1800 -j "$(nproc)" -L '^(unit|unit-shared|stability)$' -E "$convergence" "$@"
echo "sanitize: tests took $(( $(date +%s) - start )) s"
