// The stage engine: how a gather method's stages run, the one order every driver follows
// (RunStagesLocally in one process; the coordinator over the farm, across restarts).
//
// A stage's tasks come from the plan's row tiles and the artifact the previous stage combined
// (none for the first). When all of a stage's tasks are done, a non-final stage's outputs, in
// task order, combine into the next stage's artifact (Hašan 2007: sample rows → cluster →
// accumulate columns); the final stage's outputs, in task order, become the rows of the image.
// Counters and method stats add up over every task of every stage in (stage, task) order. A
// driver that follows this order gets the same bits as any other, whatever ran the tasks.
#pragma once

#include <string>
#include <vector>

#include "common/render/render_job.h"

namespace lightfarm {

class StageEngine {
 public:
  explicit StageEngine(const Plan& plan) : plan_(plan) {}

  int stage_count() const;
  std::string stage_name(int stage) const;
  bool is_final(int stage) const { return stage + 1 >= stage_count(); }

  // The tasks of `stage`, planned from the previous stage's artifact (empty for stage 0).
  std::vector<SubMatrixTask> Tasks(int stage, const StageArtifact& previous) const;
  // Ends a non-final stage: its outputs, in task order, combined into the next stage's input.
  StageArtifact Combine(int stage, const std::vector<TaskOutput>& outputs) const;

  // The outcome: Count every task's output of every stage in (stage, task) order, and AddFinal
  // the final stage's (in task order; throws std::runtime_error when an output does not fit).
  void Count(const TaskOutput& out);
  void AddFinal(const SubMatrixTask& task, const TaskOutput& out);
  GatherOutcome& outcome();

 private:
  const Plan& plan_;
  GatherOutcome outcome_;
  bool started_ = false;
};

// The outcome of the final stage's outputs alone (the coordinator's preview of finished tiles):
// the others' rows stay black.
GatherOutcome PartialOutcome(const Plan& plan, const std::vector<std::pair<SubMatrixTask, TaskOutput>>& done);

}  // namespace lightfarm
