// The interface every many-light method implements: given a sub-matrix (a set of receiver rows
// against the light set), return each row's RGB sum over all columns, plus what it cost. One
// method, one file (mitsuba-style), found by name in the registry (registry.cpp), so that the
// farm can distribute any of them. Nothing here knows about networking.
//
// A method is a small graph of stages (DESIGN.md): each stage is a set of tasks that may run on
// workers; between two stages the coordinator combines the tasks' payloads into an artifact that
// every task of the next stage receives (MRCS: sample rows → cluster → accumulate columns).
// Single-stage methods (brute, lightcuts) only implement RunTask.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/lights/light_tree.h"
#include "common/matrix/lighting_matrix.h"
#include "common/util/options.h"

namespace lightfarm {

struct SubMatrixTask {
  uint32_t stage = 0;
  uint32_t task_id = 0;
  std::vector<uint32_t> rows;       // receiver (shading point) indices
  std::vector<uint32_t> neighbors;  // ids of neighbouring tasks (slices), when a method needs them
  uint64_t seed = 0;  // job seed; methods derive randomness from (seed, stage, task, index)
  // Film methods (GatherMethod::renders_film): `rows` are pixel indices (y * width + x) and the
  // task takes camera samples [sample_begin, sample_end) of each.
  uint32_t sample_begin = 0, sample_end = 0;
};

// What a task returns: row sums in the final stage, a method-defined payload in earlier ones.
struct TaskOutput {
  std::vector<RGBAccum> row_sums;  // final stage: one per task row, same order
  // Film methods: Σ w per pixel row (row_sums then hold Σ w·L), w the filter weight of each
  // camera sample; empty for matrix methods.
  std::vector<double> row_weights;
  std::vector<uint8_t> payload;    // earlier stages: input to Combine
  MatrixCounters counters;
  std::map<std::string, double> stats;  // method-specific numbers, summed over tasks
};

using StageArtifact = std::vector<uint8_t>;

// What a method may read besides its task. Everything here is deterministic in the job seed, so
// a worker holds the same context as the coordinator.
struct GatherContext {
  const LightingMatrix& matrix;
  const LightTree* tree = nullptr;  // set when the method's needs_light_tree()
};

class GatherMethod {
 public:
  virtual ~GatherMethod() = default;
  virtual std::string name() const = 0;
  virtual int stage_count() const { return 1; }
  virtual bool needs_light_tree() const { return false; }
  // Whether the method gathers media rows and columns (eye segments, medium VPLs). Methods that
  // only sample matrix entries do; a method that bounds elements analytically (lightcuts) needs
  // bounds for every element type first, and until then sees media as attenuation only.
  virtual bool gathers_media() const { return true; }
  // Whether the method renders the film directly (a path tracer) instead of gathering a lighting
  // matrix: its plan has no receivers or virtual lights, its tasks are pixel tiles × sample
  // ranges (SubMatrixTask), and a pixel may appear in several tasks, summed in task order.
  virtual bool renders_film() const { return false; }
  // Whether its rows may be receivers of coverage paths (ReceiverOptions::coverage): a few points
  // per pixel whose throughput is their share of it, some of them small. A method whose estimate
  // leans on a handful of uniformly drawn rows per slice says no: the default is then one path
  // per sample.
  virtual bool takes_coverage_rows() const { return true; }
  virtual std::string stage_name(int stage) const { return stage == 0 ? "gather" : "stage" + std::to_string(stage); }

  // The tasks of a stage. `tiles` are the plan's row partitions (slices), covering every row once;
  // the final stage must cover every row exactly once. Default: the tiles themselves.
  virtual std::vector<SubMatrixTask> PlanStage(int stage, const GatherContext& ctx,
                                               const std::vector<SubMatrixTask>& tiles,
                                               const StageArtifact& previous) const;
  // Runs one task. Must be deterministic for a given (stage, task, seed), whatever the thread
  // count, so that a retried or re-run task gives the same bits.
  virtual TaskOutput RunTask(const GatherContext& ctx, const SubMatrixTask& task,
                             const StageArtifact& previous) const = 0;
  // The coordinator's step after a non-final stage: outputs are in task-id order.
  virtual StageArtifact Combine(int stage, const GatherContext& ctx,
                                const std::vector<TaskOutput>& outputs) const;
};

// Runs one task as every driver must (the embedded stage loop and the workers): the method's
// RunTask, then, on the final stage of a matrix method, each row's ExtraLight (the clamp's
// compensation, the caustics) added to its sum (rows in parallel, summed in row order).
TaskOutput RunGatherTask(const GatherMethod& method, const GatherContext& ctx, const SubMatrixTask& task,
                         const StageArtifact& previous);

// What a method declares about itself besides its algorithm, in its own file, next to it
// (registry.cpp lists the methods): how to create it, how `lightfarm bench` sweeps it and its
// documented parameters for a target error. What `auto` knows of it is measured, not declared:
// the bench results MethodChooser reads (common/render/method_chooser.h).
struct GatherMethodInfo {
  std::string name;
  std::function<std::unique_ptr<GatherMethod>(const OptionMap&)> create;
  // The bench's settings: ';'-separated --param lists, cheapest first, >= 5; "" = not swept.
  std::string sweep;
  // --target-error without bench results for the scene: the documented parameters for a
  // relative error; unset = no such default.
  std::function<std::vector<std::string>(double target)> params_for_target;
};

// Every method of this build, in registry order.
const std::vector<GatherMethodInfo>& GatherMethods();
// nullptr for a name no method has.
const GatherMethodInfo* FindGatherMethod(const std::string& name);

// Creates a method by name, reading its parameters from `params` (marking them used).
// Throws OptionError for an unknown method or an invalid parameter value.
std::unique_ptr<GatherMethod> CreateGatherMethod(const std::string& name, const OptionMap& params);
std::vector<std::string> GatherMethodNames();

}  // namespace lightfarm
