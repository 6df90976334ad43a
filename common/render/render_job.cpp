#include "common/render/render_job.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <functional>

#include "common/render/method_chooser.h"
#include "common/render/render_options.h"
#include "common/render/stage_engine.h"
#include "common/image/film.h"
#include "common/image/filter.h"
#include "common/lights/light_generation.h"
#include "common/receivers/segment_slicing.h"
#include "common/receivers/slicing.h"
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
    if (times_) times_->Add(name, Seconds(start_, now));
    start_ = now;
  }

 private:
  PhaseTimes* times_;
  Clock::time_point start_;
};

// Film methods' tasks: tiles of tile × tile pixels (row-major), each split into passes of
// pass_spp camera samples, pass-major so that a partial result covers the whole image.
std::vector<SubMatrixTask> FilmTasks(int width, int height, int spp, int tile, int pass_spp,
                                     uint64_t seed) {
  std::vector<SubMatrixTask> tasks;
  for (int begin = 0; begin < spp; begin += pass_spp) {
    for (int ty = 0; ty < height; ty += tile) {
      for (int tx = 0; tx < width; tx += tile) {
        SubMatrixTask task;
        task.task_id = uint32_t(tasks.size());
        task.seed = seed;
        task.sample_begin = uint32_t(begin);
        task.sample_end = uint32_t(std::min(spp, begin + pass_spp));
        for (int y = ty; y < std::min(height, ty + tile); ++y)
          for (int x = tx; x < std::min(width, tx + tile); ++x) task.rows.push_back(uint32_t(y * width + x));
        tasks.push_back(std::move(task));
      }
    }
  }
  return tasks;
}

// The steps BuildPlan and RebuildPlan share, so a worker's plan is the coordinator's.

// The scene as the settings override it (resolution, pixel filter).
std::unique_ptr<Scene> BuildSceneFor(const SceneDescription& desc, const RenderSettings& settings) {
  SceneBuildOptions build;
  build.width = settings.width;
  build.height = settings.height;
  build.filter = settings.filter;
  return Scene::Build(desc, build);
}

// `auto` resolved on the scene's effects (MethodChooser::ForScene), or the method named. A
// choice that carries settings adds them to `params` (a key the user set wins).
void ChooseMethod(const RenderSettings& settings, OptionMap* params, Plan* plan) {
  if (settings.method == kAutoMethod) {
    const MethodChoice choice = MethodChooser::BuiltIn().ForScene(plan->effects, settings.lights, *params);
    params->AddMissing(choice.params);
    const std::string rule = choice.rule + (choice.setting.empty() ? "" : ": " + choice.setting);
    spdlog::info("method auto resolved to {} (rule: {})", choice.method, rule);
    plan->method = CreateGatherMethod(choice.method, *params);
    plan->method_rule = rule;
  } else {
    plan->method = CreateGatherMethod(settings.method, *params);
    plan->method_rule = settings.method_rule;
  }
}

// The sharp-lobe split, before any BSDF is read: matrix methods only (a film method traces the
// scene's own BSDFs).
void ApplySharpSplit(const RenderSettings& settings, Plan* plan) {
  if (plan->method->renders_film()) return;
  // The near field is part of the split: sharp_roughness=0 turns both off.
  const float alpha = SharpAlpha(plan->matrix_options, settings.lights);
  plan->scene->SetSharpAlpha(alpha, plan->matrix_options.near_sharp && alpha > 0 ? kNearSharpMaxAlpha : 0.f);
}

// Camera-side supersampling by default only when a camera path can collect something by itself:
// it can see an emitter (an area light, an environment) or take emitter samples at a sharp
// vertex. Then the pixels the pilot marks (a visible light's edge, a light's reflection in a
// sharp lobe) get 256 more camera paths: a few rays each, against the hundreds to thousands of
// shadow rays of one receiver's gather. docs/default-vs-path.md measures the effect.
// Materials with a lobe the sharp split made sharp, near-field twins included.
size_t SharpMaterials(const Scene& scene) {
  size_t n = 0;
  for (const Material& m : scene.materials()) n += HasSharpLobe(m);
  return n;
}

int CameraPathsFor(const Scene& scene, const Effects& effects, bool media_direct) {
  if (effects.area_lights || effects.environment || SharpMaterials(scene) > 0) return kDefaultCameraPaths;
  return media_direct ? kDefaultMediaCameraPaths : 0;
}

// The virtual lights a render draws on the surfaces, before the media's options: the render's
// own set (seeded by the job) and the near-field rule's stand-in (receivers.cpp) alike.
LightGenerationOptions LightOptionsFor(const RenderSettings& settings, const RenderOptions& options,
                                       const Scene& scene) {
  LightGenerationOptions lopt;
  lopt.target_lights = settings.lights;
  lopt.direct_fraction = options.direct_fraction;
  lopt.max_depth = scene.hints().max_depth;
  lopt.seed = settings.seed;
  lopt.quasi_random_paths = options.quasi_random_paths;
  return lopt;
}

// The light tree (when the method needs one) and the matrix over the plan's receivers and lights.
void AttachMatrix(const RenderSettings& settings, Plan* plan) {
  if (plan->method->renders_film()) {
    plan->matrix_options.caustic_photons = 0;  // the path tracer finds caustics by itself
  } else if (plan->method->needs_light_tree()) {
    plan->tree = std::make_unique<LightTree>(LightTree::Build(*plan->lights, settings.seed));
  }
  plan->matrix = std::make_unique<LightingMatrix>(*plan->scene, *plan->receivers, *plan->lights, plan->matrix_options);
}

// BuildPlan's steps; `scene_desc` gives the scene description once the settings are checked.
Plan BuildPlanWith(const std::function<const SceneDescription&()>& scene_desc, const RenderSettings& settings,
                   PhaseTimes* times) {
  PhaseTimer timer(times);
  OptionMap params = OptionMap::Parse(settings.params);
  Plan plan;
  const RenderOptions options = ReadRenderOptions(params, settings.seed);
  plan.clamp = options.clamp;
  plan.matrix_options = options.matrix;
  // `auto` resolves once the scene's effects are known (below); until then only its own
  // parameter can be checked, and a typo in the others is reported after the scene is built.
  const bool auto_method = settings.method == kAutoMethod;
  MethodRenderOptions method_options;
  if (auto_method) {
    CheckGatherMethodOptions(settings.method, params);
  } else {
    ChooseMethod(settings, &params, &plan);
    method_options = ReadMethodRenderOptions(params, *plan.method);
    params.RejectUnused();
  }
  if (settings.spp < 0) throw OptionError("--spp must be >= 1 (or 0 for the method's default)");
  if (settings.lights < 1) throw OptionError("--lights must be >= 1");

  const SceneDescription& desc = scene_desc();
  timer.End("parse");
  plan.scene = BuildSceneFor(desc, settings);
  const Scene& scene = *plan.scene;
  plan.effects = ComputeEffects(scene);
  if (auto_method) {
    ChooseMethod(settings, &params, &plan);
    method_options = ReadMethodRenderOptions(params, *plan.method);
    params.RejectUnused();
  }
  if (plan.method->renders_film()) {
    // A film method traces its own camera paths: no receivers, virtual lights or slices. The
    // receiver set only carries the film's size and samples per pixel (the scene's Sampler
    // "pixelsamples" unless --spp overrides it).
    timer.End("build");
    plan.receivers->width = scene.hints().width;
    plan.receivers->height = scene.hints().height;
    plan.receivers->spp = settings.spp > 0 ? settings.spp : std::max(1, scene.hints().pixel_samples);
    AttachMatrix(settings, &plan);
    plan.tasks = FilmTasks(plan.receivers->width, plan.receivers->height, plan.receivers->spp,
                           method_options.film_tile, method_options.film_pass_spp, settings.seed);
    timer.End("plan");
    return plan;
  }
  // Eye segments and medium VPLs exist only when a medium is reachable, and only for gather
  // methods that evaluate those rows and columns (GatherMethod::gathers_media). Others still see
  // media as attenuation of surface transport, and say so.
  const bool media_rows = plan.effects.media && plan.method->gathers_media();
  if (plan.effects.media && !media_rows)
    spdlog::warn("method {} does not gather media rows yet: in-scattered light is omitted, media only "
                 "attenuate surface transport (use another method for the full image)",
                 plan.method->name());
  timer.End("build");

  ApplySharpSplit(settings, &plan);
  std::unique_ptr<Filter> filter = MakePixelFilter(scene.hints());
  FilterSampler filter_sampler(*filter);
  ReceiverOptions ropt;
  ropt.spp = std::max(1, settings.spp);
  ropt.seed = settings.seed;
  ropt.max_depth = scene.hints().max_depth;
  ropt.segments_per_ray = media_rows ? options.segments_per_ray : -1;
  ropt.media_direct_samples = media_rows ? plan.matrix_options.media_direct_samples : 0;
  ropt.sharp_samples = plan.matrix_options.sharp_samples;
  ropt.splits = plan.matrix_options.splits;
  // The near-field rule's own light set: drawn like the render's surface lights (below); the
  // receivers give it its own seed.
  if (scene.near_sharp_twins() > 0) ropt.near_sharp_lights = LightOptionsFor(settings, options, scene);
  ropt.coverage = method_options.coverage;
  ropt.coverage_shadows = method_options.coverage_shadows;
  // Refined slices split segments at their boundaries, which a row of several rays' pieces has
  // no single place for: refinement keeps one ray per row.
  ropt.segment_coverage = options.segment_slicing.refine ? 1 : method_options.segment_coverage;
  ropt.camera_paths = options.camera_paths.value_or(CameraPathsFor(scene, plan.effects, ropt.media_direct_samples > 0));
  *plan.receivers = GenerateReceivers(scene, filter_sampler, ropt);
  timer.End("receivers");
  // Segment slices before anything refers to the segments: refinement may split some of them.
  std::vector<Slice> segment_slices = SliceSegments(scene, plan.receivers.get(), options.segment_slicing);
  if (!segment_slices.empty()) timer.End("segment_slicing");

  LightGenerationOptions lopt = LightOptionsFor(settings, options, scene);
  lopt.medium_lights = media_rows ? options.media_lights : MediumLights::kNone;
  lopt.vrl_pieces = options.vrl_pieces;
  *plan.lights = GenerateLights(scene, lopt);
  plan.light_options = lopt;
  timer.End("lights");
  AttachMatrix(settings, &plan);
  if (plan.tree) timer.End("light_tree");
  // Row tiles: slices of receivers clustered by position and normal (slicing.h), one task each.
  std::vector<Slice> slices =
      SliceReceivers(*plan.receivers, Length(scene.bounds().Diagonal()), options.slicing);
  for (Slice& slice : slices) {
    SubMatrixTask task;
    task.task_id = uint32_t(plan.tasks.size());
    task.seed = settings.seed;
    task.rows = std::move(slice.rows);
    task.neighbors = std::move(slice.neighbors);
    plan.tasks.push_back(std::move(task));
  }
  // Eye-segment rows (after the point rows): the segment slices, their neighbours renumbered
  // to task ids.
  const size_t npoints = plan.matrix->point_rows();
  const uint32_t first_segment_task = uint32_t(plan.tasks.size());
  for (Slice& slice : segment_slices) {
    SubMatrixTask task;
    task.task_id = uint32_t(plan.tasks.size());
    task.seed = settings.seed;
    task.rows.reserve(slice.rows.size());
    for (uint32_t s : slice.rows) task.rows.push_back(uint32_t(npoints + s));
    for (uint32_t n : slice.neighbors) task.neighbors.push_back(first_segment_task + n);
    plan.tasks.push_back(std::move(task));
  }
  timer.End("plan");
  return plan;
}

}  // namespace

Plan BuildPlan(const std::string& scene_path, const RenderSettings& settings, PhaseTimes* times) {
  SceneDescription parsed;
  return BuildPlanWith(
      [&]() -> const SceneDescription& {
        parsed = ParseSceneFile(scene_path);
        return parsed;
      },
      settings, times);
}

Plan BuildPlan(const SceneDescription& desc, const RenderSettings& settings, PhaseTimes* times) {
  return BuildPlanWith([&]() -> const SceneDescription& { return desc; }, settings, times);
}

Plan RebuildPlan(const SceneDescription& desc, const RenderSettings& settings, double clamp, LightSet lights,
                 ReceiverSet receivers) {
  OptionMap params = OptionMap::Parse(settings.params);
  Plan plan;
  plan.clamp = clamp;
  plan.matrix_options = ReadRenderOptions(params, settings.seed).matrix;
  plan.matrix_options.clamp = float(clamp);
  plan.scene = BuildSceneFor(desc, settings);
  plan.effects = ComputeEffects(*plan.scene);
  ChooseMethod(settings, &params, &plan);
  ApplySharpSplit(settings, &plan);
  *plan.lights = std::move(lights);
  *plan.receivers = std::move(receivers);
  AttachMatrix(settings, &plan);
  return plan;
}

GatherOutcome RunStagesLocally(const Plan& plan, const ProgressFn& progress, PhaseTimes* times) {
  PhaseTimer timer(times);
  StageEngine engine(plan);
  const GatherContext ctx = plan.context();
  StageArtifact artifact;
  for (int stage = 0; stage < engine.stage_count(); ++stage) {
    const std::vector<SubMatrixTask> tasks = engine.Tasks(stage, artifact);
    std::vector<TaskOutput> outputs(tasks.size());
    for (size_t t = 0; t < tasks.size(); ++t) {
      outputs[t] = RunGatherTask(*plan.method, ctx, tasks[t], artifact);
      engine.Count(outputs[t]);
      if (progress) progress(engine.stage_name(stage), t + 1, tasks.size());
    }
    if (!engine.is_final(stage)) {
      artifact = engine.Combine(stage, outputs);
    } else {
      for (size_t t = 0; t < tasks.size(); ++t) engine.AddFinal(tasks[t], outputs[t]);
    }
    timer.End(engine.stage_name(stage));
  }
  return std::move(engine.outcome());
}

void SampleRows(const Plan& plan, const CameraSample& cs, std::vector<uint32_t>* rows) {
  for (uint32_t k = 0; k < cs.point_count; ++k) rows->push_back(uint32_t(cs.first_point) + k);
  // In-scattered light along the sample's eye segments (rows after the point rows).
  const size_t npoints = plan.receivers->points.size();
  for (uint32_t k = 0; k < cs.segment_count; ++k)
    rows->push_back(uint32_t(npoints + size_t(cs.first_segment) + k));
}

RGB SampleRadiance(const Plan& plan, const CameraSample& cs, const std::vector<RGBAccum>& row_sums) {
  RGBAccum L;
  L.Add(cs.emitted);
  for (uint32_t k = 0; k < cs.point_count; ++k) L.Add(row_sums[size_t(cs.first_point) + k]);
  const size_t npoints = plan.receivers->points.size();
  for (uint32_t k = 0; k < cs.segment_count; ++k)
    L.Add(row_sums[npoints + size_t(cs.first_segment) + k]);
  return L.ToRGB();
}

size_t FinalRows(const Plan& plan) {
  return plan.method->renders_film() ? size_t(plan.receivers->width) * size_t(plan.receivers->height)
                                     : plan.matrix->rows();
}

GatherOutcome StartOutcome(const Plan& plan) {
  GatherOutcome outcome;
  const size_t rows = FinalRows(plan);
  outcome.row_sums.resize(rows);
  if (plan.method->renders_film())
    outcome.row_weights.resize(rows);
  else
    outcome.row_covered.resize(rows);
  return outcome;
}

std::string CheckFinalOutput(const Plan& plan, const SubMatrixTask& task, const TaskOutput& out) {
  const size_t rows = FinalRows(plan);
  if (out.row_sums.size() != task.rows.size())
    return "result has " + std::to_string(out.row_sums.size()) + " rows, the task has " +
           std::to_string(task.rows.size());
  const size_t weights = plan.method->renders_film() ? task.rows.size() : 0;
  if (out.row_weights.size() != weights)
    return "result has " + std::to_string(out.row_weights.size()) + " row weights, expected " +
           std::to_string(weights);
  for (uint32_t r : task.rows)
    if (r >= rows) return "task row " + std::to_string(r) + " is out of range";
  return "";
}

void AddFinalOutput(const Plan& plan, const SubMatrixTask& task, const TaskOutput& out,
                    GatherOutcome* outcome) {
  const std::string problem = CheckFinalOutput(plan, task, out);
  if (!problem.empty()) throw std::runtime_error(plan.method->name() + ": " + problem);
  if (plan.method->renders_film()) {
    // Pixel sums of one sample range: added, so the order of calls (task ids) fixes the bits.
    for (size_t i = 0; i < task.rows.size(); ++i) {
      outcome->row_sums[task.rows[i]].Add(out.row_sums[i]);
      outcome->row_weights[task.rows[i]] += out.row_weights[i];
    }
    return;
  }
  for (size_t i = 0; i < task.rows.size(); ++i) {
    if (outcome->row_covered[task.rows[i]]++)
      throw std::runtime_error(plan.method->name() + ": row " + std::to_string(task.rows[i]) + " gathered twice");
    outcome->row_sums[task.rows[i]] = out.row_sums[i];
  }
}

Image AssembleImage(const Plan& plan, const GatherOutcome& outcome, uint64_t* nan_samples) {
  Film film(plan.receivers->width, plan.receivers->height);
  if (plan.method->renders_film()) {
    for (size_t p = 0; p < outcome.row_sums.size(); ++p) {
      const RGBAccum& s = outcome.row_sums[p];
      film.AddPixelSums(int(p), FilmPixel{s.r, s.g, s.b, outcome.row_weights[p]});
    }
    const auto nonfinite = outcome.method_stats.find(plan.method->name() + ".nonfinite_samples");
    if (nan_samples) *nan_samples = nonfinite == outcome.method_stats.end() ? 0 : uint64_t(nonfinite->second);
    return film.Resolve();
  }
  for (const CameraSample& cs : plan.receivers->samples)
    film.AddSample(int(cs.pixel), SampleRadiance(plan, cs, outcome.row_sums), cs.weight);
  if (nan_samples) *nan_samples = film.nan_samples();
  return film.Resolve();
}

nlohmann::json MakeStats(const Plan& plan, const RenderSettings& settings,
                         const GatherOutcome& outcome, uint64_t nan_samples,
                         const PhaseTimes& times, double total_seconds) {
  const LightSetStats& ls = plan.lights->stats;
  const MatrixCounters& counters = outcome.counters;
  nlohmann::json s;
  s["method"] = plan.method->name();
  s["method_requested"] = settings.method;
  if (!plan.method_rule.empty()) s["method_rule"] = plan.method_rule;
  s["seed"] = settings.seed;
  s["resolution"] = {plan.receivers->width, plan.receivers->height};
  s["spp"] = plan.receivers->spp;
  s["filter"] = plan.scene->hints().filter_type;
  s["effects"] = plan.effects.Names();
  s["lights"] = {{"vpl", ls.area_vpls + ls.surface_vpls},
                 {"vrl", ls.vrls},
                 {"vrl_flights", ls.vrl_flights},
                 {"medium_vpl", ls.medium_vpls},
                 {"total", plan.lights->size()},
                 {"requested", settings.lights},
                 {"area_vpl", ls.area_vpls},
                 {"surface_vpl", ls.surface_vpls},
                 {"caustic_vpl", ls.caustic_vpls},
                 {"glossy_vpl", ls.glossy_vpls},
                 {"point", ls.point_lights},
                 {"directional", ls.directional_lights},
                 {"particle_paths", ls.particle_paths}};
  s["receivers"] = {{"points", plan.receivers->points.size()},
                    {"segments", plan.receivers->segments.size()},
                    {"camera_samples", plan.receivers->samples.size()},
                    {"camera_paths", plan.receivers->stats.camera_paths},
                    {"camera_pilot_paths", plan.receivers->stats.camera_pilot_paths},
                    {"camera_active_pixels", plan.receivers->stats.camera_active_pixels},
                    {"media_direct_samples", plan.receivers->stats.media_direct_samples},
                    {"specular_bounces", plan.receivers->stats.specular_bounces},
                    {"split_vertices", plan.receivers->stats.split_vertices},
                    {"near_sharp_vertices", plan.receivers->stats.near_sharp_vertices},
                    {"coverage_paths", plan.receivers->stats.coverage_paths},
                    {"segment_coverage", plan.receivers->stats.segment_coverage},
                    {"segment_pieces", plan.receivers->segment_pieces.size()},
                    {"points_per_sample", plan.receivers->samples.empty() ? 0.0
                                          : double(plan.receivers->points.size()) / double(plan.receivers->samples.size())},
                    {"escaped", plan.receivers->stats.escaped},
                    {"transmittance_evals", plan.receivers->stats.transmittance_evals}};
  s["media"] = {{"tracks", plan.matrix->medium_tracks()}, {"track_knots", plan.matrix->medium_track_knots()}};
  s["slices"] = plan.tasks.size();
  s["tasks"] = outcome.tasks;
  const size_t nrows = plan.matrix->rows();
  const double full = double(nrows) * double(plan.lights->size());
  s["matrix"] = {{"rows", nrows},
                 {"cols", plan.lights->size()},
                 {"elements_evaluated", counters.elements},
                 {"transmittance_evals", counters.transmittance_evals},
                 {"fraction_evaluated", full > 0 ? double(counters.elements) / full : 0.0}};
  const double pixels = double(plan.receivers->width) * plan.receivers->height;
  const auto film_camera_rays = outcome.method_stats.find(plan.method->name() + ".camera_rays");
  s["rays"] = {{"shadow", counters.shadow_rays},
               {"camera", plan.method->renders_film() && film_camera_rays != outcome.method_stats.end()
                              ? uint64_t(film_camera_rays->second)
                              : uint64_t(plan.receivers->stats.camera_rays)},
               {"shadow_per_pixel", double(counters.shadow_rays) / pixels}};
  // Share of the (unclamped) light reaching receivers that the clamp removed.
  double total_lum = 0;
  if (!plan.method->renders_film())
    for (const RGBAccum& r : outcome.row_sums) total_lum += 0.2126 * r.r + 0.7152 * r.g + 0.0722 * r.b;
  // The row sums include the compensation; the unclamped total replaces it by what was lost.
  const double denom = total_lum - counters.clamp_compensated + counters.clamp_lost;
  s["clamp"] = {{"relative", plan.clamp},
                {"distance", plan.matrix->clamp_distance()},
                // The fractions' denominator (row-sum luminance); the clamp probe
                // (common/evaluation/clamp_probe.h) measures against it too.
                {"unclamped_luminance", denom},
                {"energy_lost_fraction", denom > 0 ? counters.clamp_lost / denom : 0.0},
                {"compensation_samples", plan.matrix_options.compensation_samples},
                {"media_compensation", plan.matrix->compensates_media()},
                {"compensated_fraction", denom > 0 ? counters.clamp_compensated / denom : 0.0},
                {"energy_lost_after_compensation",
                 denom > 0 ? (counters.clamp_lost - (plan.matrix->compensates() ? counters.clamp_compensated : 0.0)) / denom
                           : 0.0},
                {"compensation_paths", counters.compensation_paths},
                {"bsdf_clamp", plan.matrix_options.bsdf_clamp},
                {"bound_elements", counters.bound_elements},
                {"bound_lost_fraction", denom > 0 ? counters.bound_lost / denom : 0.0}};
  // Caustics gathered from photons (caustic_photons.h): zero unless the scene has delta lobes
  // on light paths (or --param caustic_photons asks for them).
  // The sharp-lobe split (docs/rendering.md): its threshold and the materials it made sharp.
  s["sharp"] = {{"alpha", plan.method->renders_film() ? 0.0 : double(SharpAlpha(plan.matrix_options, settings.lights))},
                {"materials", SharpMaterials(*plan.scene) - plan.scene->near_sharp_twins()},
                {"near_twins", plan.scene->near_sharp_twins()}};
  s["caustics"] = {{"photons", plan.matrix->caustic_photon_target()},
                   {"photons_used", counters.caustic_photons_used},
                   {"energy_fraction", total_lum > 0 ? counters.caustic_gathered / total_lum : 0.0}};
  s["film"] = {{"nan_samples", nan_samples}};
  s["method_stats"] = nlohmann::json::object();
  for (const auto& [k, v] : outcome.method_stats) s["method_stats"][k] = v;
  s["time"]["total_s"] = total_seconds;
  nlohmann::json phases = nlohmann::json::object();
  for (const auto& [name, secs] : times.phases) phases[name] = secs;
  s["time"]["phases"] = phases;
  return s;
}

RenderOutput RenderScene(const std::string& scene_path, const RenderSettings& settings,
                         const ProgressFn& progress) {
  const auto t_start = Clock::now();
  PhaseTimes times;
  Plan plan = BuildPlan(scene_path, settings, &times);
  GatherOutcome outcome = RunStagesLocally(plan, progress, &times);
  PhaseTimer timer(&times);
  RenderOutput out;
  uint64_t nan_samples = 0;
  out.image = AssembleImage(plan, outcome, &nan_samples);
  timer.End("film");
  out.stats = MakeStats(plan, settings, outcome, nan_samples, times, Seconds(t_start, Clock::now()));
  out.stats["scene"] = scene_path;
  return out;
}

}  // namespace lightfarm
