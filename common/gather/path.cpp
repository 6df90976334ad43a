// `path`: the unidirectional volumetric path tracer (common/integrator/path_tracer.h) as a method,
// so that it runs on the farm like every other: a film method (GatherMethod::renders_film) whose
// tasks are pixel tiles × camera-sample ranges. It is what a user would run instead of a
// many-light method, and the truth the others are measured against at equal time.
//
// Sample s of pixel p: the film position is the s-th point of the pixel's scrambled Sobol
// sequence warped by the pixel filter (filter importance sampling, as the receivers are), and
// every other decision draws from a generator seeded with (job seed, p, s). A pixel's sums are
// therefore the same whichever task, thread or worker computes a sample range.
//
// Parameters: strategy=mis|bsdf|light (which estimators the tracer combines; `bsdf` and `light`
// alone exist to check the MIS weights and for measurements). The tiling is the plan's
// (`tile`, `pass_spp`: render_job.cpp).
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "common/gather/methods.h"
#include "common/integrator/path_tracer.h"
#include "common/receivers/receivers.h"
#include "common/util/sampling.h"

namespace lightfarm {

namespace {

class PathGather final : public GatherMethod {
 public:
  explicit PathGather(PathStrategy strategy) : strategy_(strategy) {}
  std::string name() const override { return "path"; }
  bool renders_film() const override { return true; }

  TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                     const StageArtifact&) const override {
    const Scene& scene = ctx.matrix.scene();
    const int width = ctx.matrix.receivers().width;
    const std::unique_ptr<Filter> filter = MakePixelFilter(scene.hints());
    const FilterSampler filter_sampler(*filter);
    PathTracerOptions opt;
    opt.max_depth = scene.hints().max_depth;
    opt.strategy = strategy_;
    const PathTracer tracer(scene, opt);

    TaskOutput out;
    out.row_sums.resize(task.rows.size());
    out.row_weights.resize(task.rows.size());
    tbb::combinable<PathCounters> counters;
    tbb::combinable<uint64_t> nonfinite;
    tbb::parallel_for(size_t(0), task.rows.size(), [&](size_t i) {
      const uint32_t pixel = task.rows[i];
      const int x = int(pixel % uint32_t(width)), y = int(pixel / uint32_t(width));
      Rng pixel_rng(HashSeed({task.seed, uint64_t(RngStream::kPathSample), pixel}));
      const uint32_t scramble0 = pixel_rng.Next(), scramble1 = pixel_rng.Next();
      PathCounters& c = counters.local();
      RGBAccum sum;
      double weight = 0;
      for (uint32_t s = task.sample_begin; s < task.sample_end; ++s) {
        Rng rng(HashSeed({task.seed, uint64_t(RngStream::kPathSample), pixel, s}));
        const Vec2 u{Sobol2DComponent(s, 0, scramble0), Sobol2DComponent(s, 1, scramble1)};
        const FilterSample fs = filter_sampler.Sample(u);
        const Vec2 p_film{float(x) + 0.5f + fs.p.x, float(y) + 0.5f + fs.p.y};
        const Ray ray = scene.camera().GenerateRay(p_film, {rng.Uniform(), rng.Uniform()});
        RGB L(0.f);
        if (IsFinite(ray.o) && IsFinite(ray.d)) L = tracer.Li(ray, rng, &c);
        if (!L.IsFinite() || !std::isfinite(fs.weight)) {
          ++nonfinite.local();  // as Film::AddSample: dropped and counted, never in the image
          continue;
        }
        sum.Add(L * fs.weight);
        weight += double(fs.weight);
      }
      out.row_sums[i] = sum;
      out.row_weights[i] = weight;
    });
    PathCounters total;
    counters.combine_each([&](const PathCounters& c) { total.Add(c); });
    out.counters.shadow_rays = total.shadow_rays;
    out.stats["path.camera_rays"] = double(total.paths);
    out.stats["path.vertices"] = double(total.vertices);
    out.stats["path.escaped"] = double(total.escaped);
    out.stats["path.roulette"] = double(total.roulette);
    out.stats["path.nonfinite_samples"] = double(nonfinite.combine(std::plus<uint64_t>()));
    return out;
  }

 private:
  PathStrategy strategy_;
};

}  // namespace

std::unique_ptr<GatherMethod> CreatePathGather(const OptionMap& params) {
  const std::string s = params.GetString("strategy", "mis");
  PathStrategy strategy;
  if (s == "mis") strategy = PathStrategy::kMIS;
  else if (s == "bsdf") strategy = PathStrategy::kBSDF;
  else if (s == "light") strategy = PathStrategy::kLight;
  else throw OptionError("--param strategy=" + s + ": expected mis, bsdf or light");
  return std::make_unique<PathGather>(strategy);
}

GatherMethodInfo PathMethod() {
  GatherMethodInfo m;
  m.name = "path";
  m.create = CreatePathGather;
  // What a user would run instead. Its knob is the samples per pixel (a sweep's spp=N sets
  // them; bench_run.cpp); it uses no virtual lights.
  m.sweep = "spp=4;spp=16;spp=64;spp=256;spp=1024";
  return m;
}

}  // namespace lightfarm
