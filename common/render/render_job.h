// A render job on one machine: scene → plan (receivers, lights) → gather tasks → film → image.
// The farm (coordinator/worker) runs the same plan and tasks; this is the embedded path
// `lightfarm render` uses.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/render/progressive.h"
#include "common/gather/gather.h"
#include "common/image/image.h"
#include "common/lights/light_generation.h"
#include "common/lights/virtual_light.h"
#include "common/receivers/receivers.h"
#include "common/scene/effects.h"
#include "common/scene/scene.h"

namespace lightfarm {

struct RenderSettings {
  std::string method = "brute";  // the library default; the CLI defaults to "auto" (method_chooser.h)
  int width = 0, height = 0;  // 0: the scene's Film resolution
  std::string filter;  // overrides the scene's PixelFilter when set
  int spp = 0;  // camera samples per pixel; 0: the method's default (path: the scene's, others: 1)
  size_t lights = kDefaultLights;
  uint64_t seed = 0;
  std::vector<std::string> params;  // KEY=VALUE (--param)
  // Why the client chose `method` when it resolved `auto` itself (a bench model against the
  // truth): reported as the stats' method_rule.
  std::string method_rule;
  // A progressive job's passes (progressive.h): the farm runs each with PassSeed(seed, pass).
  // Everything else here renders one pass.
  PassPlan progressive;
  // Farm jobs: every task run on two workers and compared bit for bit (docs/operations.md).
  bool verify = false;
};

// Everything a gather needs, built once per job (deterministic in the job seed).
// The matrix refers to the scene, the receivers and the lights: each lives on the heap, so a plan
// moves without touching them and the matrix stays valid.
struct Plan {
  std::unique_ptr<Scene> scene;
  Effects effects;
  std::unique_ptr<ReceiverSet> receivers = std::make_unique<ReceiverSet>();
  std::unique_ptr<LightSet> lights = std::make_unique<LightSet>();
  std::unique_ptr<LightTree> tree;  // built when the method needs it
  std::unique_ptr<LightingMatrix> matrix;
  std::unique_ptr<GatherMethod> method;
  std::string method_rule;  // when the method was `auto`: the rule that resolved it
  std::vector<SubMatrixTask> tasks;
  MatrixOptions matrix_options;
  double clamp = 0;
  LightGenerationOptions light_options;  // how plan.lights were generated (BuildPlan only)
  GatherContext context() const { return GatherContext{*matrix, tree.get()}; }
};

struct PhaseTimes {
  std::vector<std::pair<std::string, double>> phases;  // in order of execution
  void Add(const std::string& name, double seconds) { phases.emplace_back(name, seconds); }
};

// Parses and builds the scene and creates everything the gather needs. Validates settings and
// --param first, so a typo fails before any expensive work.
Plan BuildPlan(const std::string& scene_path, const RenderSettings& settings, PhaseTimes* times);
// The same from a parsed scene (SceneCache: the farm parses a job's scene once per process).
Plan BuildPlan(const SceneDescription& desc, const RenderSettings& settings, PhaseTimes* times);

// The plan a worker runs tasks of, rebuilt from the coordinator's: the scene from its
// description, the plan's clamp, virtual lights and receivers; the method, the sharp-lobe split,
// the light tree and the matrix by the steps BuildPlan takes. No tasks (the coordinator sends them).
Plan RebuildPlan(const SceneDescription& desc, const RenderSettings& settings, double clamp, LightSet lights,
                 ReceiverSet receivers);

// The result of running all of a method's stages.
struct GatherOutcome {
  std::vector<RGBAccum> row_sums;  // one per matrix row; film methods: Σ w·L per pixel
  std::vector<double> row_weights;  // film methods: Σ w per pixel
  std::vector<uint8_t> row_covered;  // matrix methods: rows added so far (each exactly once)
  MatrixCounters counters;
  std::map<std::string, double> method_stats;
  size_t tasks = 0;
};

using ProgressFn = std::function<void(const std::string& phase, size_t done, size_t total)>;

// Runs every stage of the plan's method in this process (tasks in id order; each task is
// parallel inside), driving the StageEngine (stage_engine.h) as the coordinator does.
GatherOutcome RunStagesLocally(const Plan& plan, const ProgressFn& progress, PhaseTimes* times);

// The matrix rows a camera sample's radiance sums: its shading point's row, then its eye
// segments' rows (after the point rows), in that order. Appends to `rows`.
void SampleRows(const Plan& plan, const CameraSample& cs, std::vector<uint32_t>* rows);
// A camera sample's radiance: its emission plus the row sums of SampleRows, in that order (so
// every caller adds the same floats in the same order and gets the same bits).
RGB SampleRadiance(const Plan& plan, const CameraSample& cs, const std::vector<RGBAccum>& row_sums);

// The final stage's rows: the matrix rows, or the pixels for a film method.
size_t FinalRows(const Plan& plan);
// An outcome with no final output added yet (StageEngine::outcome starts from it).
GatherOutcome StartOutcome(const Plan& plan);
// Whether a final-stage output fits its task (row count, row weights for film methods, rows in
// range): "" when it does, else what is wrong. The coordinator checks each worker's result so.
std::string CheckFinalOutput(const Plan& plan, const SubMatrixTask& task, const TaskOutput& out);
// Adds a final-stage output: matrix methods set each row exactly once, film methods add their
// pixel sums (StageEngine::AddFinal, in task-id order). Throws std::runtime_error when the
// output does not fit.
void AddFinalOutput(const Plan& plan, const SubMatrixTask& task, const TaskOutput& out,
                    GatherOutcome* outcome);

// The image: matrix methods add each camera sample's SampleRadiance to the film, film methods
// resolve their pixel sums.
Image AssembleImage(const Plan& plan, const GatherOutcome& outcome, uint64_t* nan_samples);

// The stats JSON (keys are a contract: DESIGN.md).
nlohmann::json MakeStats(const Plan& plan, const RenderSettings& settings,
                         const GatherOutcome& outcome, uint64_t nan_samples,
                         const PhaseTimes& times, double total_seconds);

struct RenderOutput {
  Image image;
  nlohmann::json stats;
};

// Parses, builds and renders. Throws SceneError / OptionError / std::runtime_error.
RenderOutput RenderScene(const std::string& scene_path, const RenderSettings& settings,
                         const ProgressFn& progress = nullptr);

}  // namespace lightfarm
