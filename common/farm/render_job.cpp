#include "common/farm/render_job.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "common/image/film.h"
#include "common/image/filter.h"
#include "common/lights/light_generation.h"
#include "common/scene/scene_description.h"

namespace lightfarm {

namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

class PhaseTimer {
 public:
  explicit PhaseTimer(PhaseTimes* times) : times_(times), start_(Clock::now()) {}
  void End(const std::string& name) {
    auto now = Clock::now();
    times_->Add(name, Seconds(start_, now));
    start_ = now;
  }

 private:
  PhaseTimes* times_;
  Clock::time_point start_;
};

std::unique_ptr<Filter> MakeFilter(const RenderHints& h) {
  FilterShape shape;
  shape.sigma = h.filter_sigma;
  shape.b = h.filter_B;
  shape.c = h.filter_C;
  shape.tau = h.filter_tau;
  return Filter::Create(ParseFilterType(h.filter_type), {h.filter_xradius, h.filter_yradius}, shape);
}

}  // namespace

RenderOutput RenderScene(const std::string& scene_path, const RenderSettings& settings,
                         const ProgressFn& progress) {
  const auto t_start = Clock::now();
  PhaseTimes times;
  PhaseTimer timer(&times);

  // Options first: a typo in --param or --method fails before any expensive work.
  OptionMap params = OptionMap::Parse(settings.params);
  Plan plan;
  plan.clamp = params.GetDouble("clamp", 0.01, 0.0, 1.0);
  plan.matrix_options.clamp = float(plan.clamp);
  float direct_fraction = float(params.GetDouble("direct_fraction", 0.5, 0.0, 1.0));
  size_t tile_rows = size_t(params.GetInt("tile_rows", 4096, 1, 1 << 24));
  plan.method = CreateGatherMethod(settings.method, params);
  params.RejectUnused();
  if (settings.spp < 1) throw OptionError("--spp must be >= 1");
  if (settings.lights < 1) throw OptionError("--lights must be >= 1");

  SceneDescription desc = ParseSceneFile(scene_path);
  timer.End("parse");
  SceneBuildOptions build;
  build.width = settings.width;
  build.height = settings.height;
  build.filter = settings.filter;
  plan.scene = Scene::Build(desc, build);
  const Scene& scene = *plan.scene;
  plan.effects = ComputeEffects(scene);
  timer.End("build");

  std::unique_ptr<Filter> filter = MakeFilter(scene.hints());
  FilterSampler filter_sampler(*filter);
  ReceiverOptions ropt;
  ropt.spp = settings.spp;
  ropt.seed = settings.seed;
  ropt.max_depth = scene.hints().max_depth;
  plan.receivers = GenerateReceivers(scene, filter_sampler, ropt);
  timer.End("receivers");

  LightGenerationOptions lopt;
  lopt.target_lights = settings.lights;
  lopt.direct_fraction = direct_fraction;
  lopt.max_depth = scene.hints().max_depth;
  lopt.seed = settings.seed;
  plan.lights = GenerateLights(scene, lopt);
  timer.End("lights");

  plan.matrix = std::make_unique<LightingMatrix>(scene, plan.receivers, plan.lights,
                                                 plan.matrix_options);
  const size_t nrows = plan.matrix->rows();
  for (size_t begin = 0; begin < nrows; begin += tile_rows) {
    SubMatrixTask task;
    task.task_id = uint32_t(plan.tasks.size());
    task.seed = settings.seed;
    for (size_t r = begin; r < std::min(nrows, begin + tile_rows); ++r)
      task.rows.push_back(uint32_t(r));
    plan.tasks.push_back(std::move(task));
  }
  timer.End("plan");

  // Gather: each task's row sums land in a per-row array (order-independent assembly).
  std::vector<RGBAccum> row_sums(nrows);
  MatrixCounters counters;
  std::map<std::string, double> method_stats;
  for (size_t t = 0; t < plan.tasks.size(); ++t) {
    const SubMatrixTask& task = plan.tasks[t];
    GatherResult r = plan.method->Run(*plan.matrix, task);
    if (r.row_sums.size() != task.rows.size())
      throw std::logic_error("gather method returned a wrong number of rows");
    for (size_t i = 0; i < task.rows.size(); ++i) row_sums[task.rows[i]] = r.row_sums[i];
    counters.Add(r.counters);
    for (const auto& [k, v] : r.stats) method_stats[k] += v;
    if (progress) progress("gather", t + 1, plan.tasks.size());
  }
  timer.End("gather");

  Film film(plan.receivers.width, plan.receivers.height);
  for (const CameraSample& cs : plan.receivers.samples) {
    RGBAccum L;
    L.Add(cs.emitted);
    if (cs.point >= 0) L.Add(row_sums[cs.point]);
    film.AddSample(int(cs.pixel), L.ToRGB(), cs.weight);
  }
  RenderOutput out;
  out.image = film.Resolve();
  timer.End("film");

  // --- Stats (keys are a contract: DESIGN.md) ------------------------------------------------
  const LightSetStats& ls = plan.lights.stats;
  nlohmann::json& s = out.stats;
  s["method"] = plan.method->name();
  s["seed"] = settings.seed;
  s["scene"] = scene_path;
  s["resolution"] = {plan.receivers.width, plan.receivers.height};
  s["spp"] = plan.receivers.spp;
  s["filter"] = scene.hints().filter_type;
  s["effects"] = plan.effects.Names();
  s["lights"] = {{"vpl", ls.area_vpls + ls.surface_vpls},
                 {"vrl", 0},
                 {"total", plan.lights.size()},
                 {"requested", settings.lights},
                 {"area_vpl", ls.area_vpls},
                 {"surface_vpl", ls.surface_vpls},
                 {"caustic_vpl", ls.caustic_vpls},
                 {"glossy_vpl", ls.glossy_vpls},
                 {"point", ls.point_lights},
                 {"directional", ls.directional_lights},
                 {"particle_paths", ls.particle_paths}};
  s["receivers"] = {{"points", plan.receivers.points.size()},
                    {"segments", 0},
                    {"camera_samples", plan.receivers.samples.size()},
                    {"specular_bounces", plan.receivers.stats.specular_bounces},
                    {"escaped", plan.receivers.stats.escaped}};
  s["slices"] = plan.tasks.size();
  const double full = double(nrows) * double(plan.lights.size());
  s["matrix"] = {{"rows", nrows},
                 {"cols", plan.lights.size()},
                 {"elements_evaluated", counters.elements},
                 {"fraction_evaluated", full > 0 ? double(counters.elements) / full : 0.0}};
  const double pixels = double(plan.receivers.width) * plan.receivers.height;
  s["rays"] = {{"shadow", counters.shadow_rays},
               {"camera", plan.receivers.stats.camera_rays},
               {"shadow_per_pixel", double(counters.shadow_rays) / pixels}};
  const double clamp_total = counters.clamp_kept + counters.clamp_lost;
  nlohmann::json luminance_sum = 0.0;
  s["clamp"] = {{"relative", plan.clamp},
                {"distance", plan.matrix->clamp_distance()},
                {"clamped_energy_lost", counters.clamp_lost},
                {"energy_lost_fraction", 0.0}};
  // Fraction of the (unclamped) light reaching receivers that the clamp removed.
  double total_lum = 0;
  for (const RGBAccum& r : row_sums) total_lum += 0.2126 * r.r + 0.7152 * r.g + 0.0722 * r.b;
  if (total_lum + counters.clamp_lost > 0)
    s["clamp"]["energy_lost_fraction"] = counters.clamp_lost / (total_lum + counters.clamp_lost);
  (void)clamp_total;
  (void)luminance_sum;
  s["film"] = {{"nan_samples", film.nan_samples()}};
  for (const auto& [k, v] : method_stats) s["method_stats"][k] = v;
  s["time"]["total_s"] = Seconds(t_start, Clock::now());
  nlohmann::json phases = nlohmann::json::object();
  for (const auto& [name, secs] : times.phases) phases[name] = secs;
  s["time"]["phases"] = phases;
  return out;
}

}  // namespace lightfarm
