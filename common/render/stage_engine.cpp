#include "common/render/stage_engine.h"

#include "common/util/check.h"

namespace lightfarm {

int StageEngine::stage_count() const { return plan_.method->stage_count(); }

std::string StageEngine::stage_name(int stage) const { return plan_.method->stage_name(stage); }

std::vector<SubMatrixTask> StageEngine::Tasks(int stage, const StageArtifact& previous) const {
  return plan_.method->PlanStage(stage, plan_.context(), plan_.tasks, previous);
}

StageArtifact StageEngine::Combine(int stage, const std::vector<TaskOutput>& outputs) const {
  CHECK(!is_final(stage));  // the final stage is not combined: its outputs are the image
  return plan_.method->Combine(stage, plan_.context(), outputs);
}

GatherOutcome& StageEngine::outcome() {
  if (!started_) {
    outcome_ = StartOutcome(plan_);
    started_ = true;
  }
  return outcome_;
}

void StageEngine::Count(const TaskOutput& out) {
  GatherOutcome& o = outcome();
  o.counters.Add(out.counters);
  for (const auto& [k, v] : out.stats) o.method_stats[k] += v;
  ++o.tasks;
}

void StageEngine::AddFinal(const SubMatrixTask& task, const TaskOutput& out) {
  AddFinalOutput(plan_, task, out, &outcome());
}

GatherOutcome PartialOutcome(const Plan& plan, const std::vector<std::pair<SubMatrixTask, TaskOutput>>& done) {
  StageEngine engine(plan);
  for (const auto& [task, out] : done) engine.AddFinal(task, out);
  return std::move(engine.outcome());
}

}  // namespace lightfarm
