// The stage engine (common/render/stage_engine.h) is the one order every driver follows: tasks may
// run in any order on any process, but a driver that combines and adds their outputs in task
// order gets the bits RunStagesLocally gets. The coordinator's resume and the farm tests rely on it.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include "common/render/render_job.h"
#include "common/render/stage_engine.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_stage_engine {

Plan CornellPlan(const std::string& method) {
  RenderSettings s;
  s.method = method;
  s.width = s.height = 16;
  s.lights = 400;
  s.seed = 5;
  return BuildPlan(testing::SourcePath("scenes/cornell-box/scene.pbrt"), s, nullptr);
}

// Runs every stage with its tasks executed last to first, as a farm might finish them.
GatherOutcome RunBackwards(const Plan& plan) {
  StageEngine engine(plan);
  StageArtifact artifact;
  for (int stage = 0; stage < engine.stage_count(); ++stage) {
    const std::vector<SubMatrixTask> tasks = engine.Tasks(stage, artifact);
    std::vector<TaskOutput> outputs(tasks.size());
    for (size_t t = tasks.size(); t-- > 0;) outputs[t] = RunGatherTask(*plan.method, plan.context(), tasks[t], artifact);
    for (const TaskOutput& out : outputs) engine.Count(out);
    if (engine.is_final(stage)) {
      for (size_t t = 0; t < tasks.size(); ++t) engine.AddFinal(tasks[t], outputs[t]);
    } else {
      artifact = engine.Combine(stage, outputs);
    }
  }
  return std::move(engine.outcome());
}

TEST(StageEngine, AnyExecutionOrderGivesTheLocalRunsBits) {
  for (const char* method : {"brute", "mrcs", "lightslice", "path"}) {
    const Plan plan = CornellPlan(method);
    const GatherOutcome local = RunStagesLocally(plan, nullptr, nullptr);
    const GatherOutcome farm = RunBackwards(plan);
    EXPECT_GE(StageEngine(plan).stage_count(), 1) << method;
    EXPECT_EQ(local.tasks, farm.tasks) << method;
    EXPECT_EQ(local.counters.shadow_rays, farm.counters.shadow_rays) << method;
    EXPECT_EQ(local.method_stats, farm.method_stats) << method;
    ASSERT_EQ(local.row_sums.size(), farm.row_sums.size()) << method;
    for (size_t i = 0; i < local.row_sums.size(); ++i) {
      ASSERT_EQ(local.row_sums[i].r, farm.row_sums[i].r) << method << " row " << i;
      ASSERT_EQ(local.row_sums[i].g, farm.row_sums[i].g) << method << " row " << i;
      ASSERT_EQ(local.row_sums[i].b, farm.row_sums[i].b) << method << " row " << i;
    }
  }
}

TEST(StageEngine, RefusesToCombineTheFinalStageOrToAddARowTwice) {
  const Plan plan = CornellPlan("brute");
  StageEngine engine(plan);
  ASSERT_EQ(engine.stage_count(), 1);
  const std::vector<SubMatrixTask> tasks = engine.Tasks(0, {});
  ASSERT_FALSE(tasks.empty());
  const TaskOutput out = RunGatherTask(*plan.method, plan.context(), tasks[0], {});
  // A broken invariant (CHECK): the process stops with file:line, it does not go on.
  EXPECT_DEATH(engine.Combine(0, {out}), "CHECK failed: !is_final\\(stage\\)");
  engine.AddFinal(tasks[0], out);
  EXPECT_THROW(engine.AddFinal(tasks[0], out), std::runtime_error);  // a retried task added twice
}

}  // namespace test_stage_engine
}  // namespace lightfarm
