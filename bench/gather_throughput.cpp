// Micro-benchmarks: how close the gathers come to Embree's raw occlusion rate. The shadow rays a
// brute-force row sum and a column evaluation issue on cornell-box are recorded once, then
// replayed through rtcOccluded1M alone; the gather's own rate (shadow rays and elements per
// second, shading included) over the replay's rate is the efficiency (target >= 0.7).
// Single-threaded on purpose: the ratio is per core. Run:
//   build/lightfarm_bench --benchmark_repetitions=5 --benchmark_enable_random_interleaving=true
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <numeric>

#include "common/render/render_job.h"
#include "common/integrator/path_tracer.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace {

constexpr size_t kBatch = 256;  // as LightingMatrix batches

struct Fixture {
  Plan plan;
  std::vector<uint32_t> brute_rows;      // rows a brute-force benchmark iteration sums
  std::vector<uint32_t> columns;         // lights a column benchmark iteration evaluates
  std::vector<uint32_t> column_rows;     // ... against these rows (one slice-sized set)
  std::vector<RTCRay> brute_rays, column_rays;
};

std::string SharedScene() {
  const char* env = std::getenv("LIGHTFARM_SHARED");
  return (env ? std::string(env) : std::string(LIGHTFARM_SOURCE_DIR) + "/../shared") +
         "/scenes/cornell-box/scene.pbrt";
}

Fixture& Get() {
  static Fixture* f = [] {
    auto* fx = new Fixture;
    RenderSettings s;
    s.width = s.height = 64;
    s.lights = 20000;
    s.seed = 1;
    fx->plan = BuildPlan(SharedScene(), s, nullptr);
    const LightingMatrix& m = *fx->plan.matrix;
    Rng rng(HashSeed({1, 0xBE7C6}));
    for (int i = 0; i < 32; ++i) fx->brute_rows.push_back(rng.UniformInt(uint32_t(m.rows())));
    for (int i = 0; i < 64; ++i) fx->columns.push_back(rng.UniformInt(uint32_t(m.cols())));
    fx->column_rows = fx->plan.tasks.front().rows;
    // Record the exact rays both gathers hand to Embree.
    MatrixCounters c;
    m.RecordShadowRays(&fx->brute_rays);
    for (uint32_t r : fx->brute_rows) m.RowSum(r, &c);
    m.RecordShadowRays(&fx->column_rays);
    std::vector<RGB> out(fx->column_rows.size());
    for (uint32_t col : fx->columns) m.Column(col, fx->column_rows, out, &c);
    m.RecordShadowRays(nullptr);
    return fx;
  }();
  return *f;
}

void SetRates(benchmark::State& state, double rays, double elements) {
  state.counters["rays/s"] = benchmark::Counter(rays, benchmark::Counter::kIsRate);
  state.counters["elements/s"] = benchmark::Counter(elements, benchmark::Counter::kIsRate);
}

void BM_GatherBruteRowSum(benchmark::State& state) {
  Fixture& f = Get();
  MatrixCounters c;
  for (auto _ : state)
    for (uint32_t r : f.brute_rows) benchmark::DoNotOptimize(f.plan.matrix->RowSum(r, &c));
  SetRates(state, double(c.shadow_rays), double(c.elements));
}

void BM_GatherColumn(benchmark::State& state) {
  Fixture& f = Get();
  MatrixCounters c;
  std::vector<RGB> out(f.column_rows.size());
  for (auto _ : state) {
    for (uint32_t col : f.columns) f.plan.matrix->Column(col, f.column_rows, out, &c);
    benchmark::DoNotOptimize(out.data());
  }
  SetRates(state, double(c.shadow_rays), double(c.elements));
}

// Replays recorded rays in the gather's batch size; tfar is restored from the pristine copy
// (Embree overwrites it) in the same pass, as the gather fills its batch.
void ReplayOcclusion(benchmark::State& state, const std::vector<RTCRay>& recorded) {
  Fixture& f = Get();
  std::vector<RTCRay> batch(kBatch);
  double rays = 0;
  for (auto _ : state) {
    for (size_t begin = 0; begin < recorded.size(); begin += kBatch) {
      const size_t n = std::min(kBatch, recorded.size() - begin);
      std::copy(recorded.begin() + long(begin), recorded.begin() + long(begin + n), batch.begin());
      f.plan.scene->Occluded(batch.data(), n);
    }
    rays += double(recorded.size());
    benchmark::DoNotOptimize(batch.data());
  }
  SetRates(state, rays, 0);
}

void BM_RawOcclusionBruteRays(benchmark::State& state) { ReplayOcclusion(state, Get().brute_rays); }
void BM_RawOcclusionColumnRays(benchmark::State& state) { ReplayOcclusion(state, Get().column_rays); }

// The path tracer (`path`) on the same scene: 2048 camera paths of the fixture's pixels, all
// their rays (closest hits and shadow rays) against the same rays replayed through Embree alone
// (Scene::Intersect, the thin wrapper the tracer calls, and rtcOccluded1M one ray at a time, as
// the tracer issues them). The difference is sampling, shading and the medium/emitter logic.
struct PathFixture {
  std::unique_ptr<PathTracer> tracer;
  std::vector<Ray> camera;
  std::vector<Ray> closest;
  std::vector<RTCRay> shadow;
};

PathFixture& GetPath() {
  static PathFixture* f = [] {
    auto* fx = new PathFixture;
    const Scene& scene = *Get().plan.scene;
    PathTracerOptions opt;
    opt.max_depth = scene.hints().max_depth;
    fx->tracer = std::make_unique<PathTracer>(scene, opt);
    Rng rng(HashSeed({2, 0xBE7C6}));
    for (int i = 0; i < 2048; ++i)
      fx->camera.push_back(scene.camera().GenerateRay({64 * rng.Uniform(), 64 * rng.Uniform()}, {0.5f, 0.5f}));
    fx->tracer->RecordRays(&fx->closest, &fx->shadow);
    PathCounters c;
    for (size_t i = 0; i < fx->camera.size(); ++i) {
      Rng path_rng(HashSeed({3, i}));
      fx->tracer->Li(fx->camera[i], path_rng, &c);
    }
    fx->tracer->RecordRays(nullptr, nullptr);
    return fx;
  }();
  return *f;
}

void BM_GatherPathTrace(benchmark::State& state) {
  PathFixture& f = GetPath();
  PathCounters c;
  double rays = 0;
  for (auto _ : state) {
    for (size_t i = 0; i < f.camera.size(); ++i) {
      Rng rng(HashSeed({3, i}));  // the recorded paths exactly
      benchmark::DoNotOptimize(f.tracer->Li(f.camera[i], rng, &c));
    }
    rays += double(f.closest.size() + f.shadow.size());
  }
  state.counters["rays/s"] = benchmark::Counter(rays, benchmark::Counter::kIsRate);
}

void BM_RawPathRays(benchmark::State& state) {
  PathFixture& f = GetPath();
  const Scene& scene = *Get().plan.scene;
  RTCRay one;
  double rays = 0;
  for (auto _ : state) {
    SurfaceHit hit;
    for (const Ray& r : f.closest) benchmark::DoNotOptimize(scene.Intersect(r, &hit));
    for (const RTCRay& r : f.shadow) {
      one = r;
      scene.Occluded(&one, 1);
    }
    benchmark::DoNotOptimize(one.tfar);
    rays += double(f.closest.size() + f.shadow.size());
  }
  state.counters["rays/s"] = benchmark::Counter(rays, benchmark::Counter::kIsRate);
}

BENCHMARK(BM_GatherPathTrace)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RawPathRays)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GatherBruteRowSum)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RawOcclusionBruteRays)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GatherColumn)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RawOcclusionColumnRays)->Unit(benchmark::kMillisecond);

// Prints the usual table, then the efficiency ratio per gather: medians over the repetitions
// (--benchmark_repetitions=N; add --benchmark_enable_random_interleaving=true on a noisy
// machine so the gather and its replay see the same load), and the spread of the ratio of
// repetition i of the gather over repetition i of the replay.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      if (r.run_type != Run::RT_Iteration) continue;  // aggregates are recomputed below
      auto it = r.counters.find("rays/s");
      if (it != r.counters.end()) rates[r.run_name.function_name].push_back(it->second.value);
    }
  }
  std::map<std::string, std::vector<double>> rates;
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace
}  // namespace lightfarm

int main(int argc, char** argv) {
  using namespace lightfarm;
  tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  std::printf("\ngather efficiency = gather shadow rays/s over raw rtcOccluded1M rays/s on the same rays "
              "(target >= 0.7)\n");
  const Fixture& f = Get();
  std::printf("recorded rays: brute %zu (%zu rows x %zu lights), column %zu (%zu columns x %zu rows)\n",
              f.brute_rays.size(), f.brute_rows.size(), f.plan.matrix->cols(), f.column_rays.size(),
              f.columns.size(), f.column_rows.size());
  const PathFixture& pf = GetPath();
  std::printf("recorded path rays: %zu closest-hit and %zu shadow rays of %zu camera paths\n", pf.closest.size(),
              pf.shadow.size(), pf.camera.size());
  for (auto [gather, raw] : {std::pair{"BM_GatherBruteRowSum", "BM_RawOcclusionBruteRays"},
                             std::pair{"BM_GatherColumn", "BM_RawOcclusionColumnRays"},
                             std::pair{"BM_GatherPathTrace", "BM_RawPathRays"}}) {
    auto g = reporter.rates.find(gather), r = reporter.rates.find(raw);
    if (g == reporter.rates.end() || r == reporter.rates.end()) continue;
    const std::vector<double>& gr = g->second;
    const std::vector<double>& rr = r->second;
    std::vector<double> paired;
    for (size_t i = 0; i < std::min(gr.size(), rr.size()); ++i) paired.push_back(gr[i] / rr[i]);
    std::printf("%-22s median %10.3g rays/s  raw median %10.3g rays/s  ratio %.2f  "
                "(%zu repetitions, paired ratios %.2f..%.2f)\n",
                gather, Median(gr), Median(rr), Median(gr) / Median(rr), gr.size(),
                *std::min_element(paired.begin(), paired.end()),
                *std::max_element(paired.begin(), paired.end()));
  }
  benchmark::Shutdown();
  return 0;
}
