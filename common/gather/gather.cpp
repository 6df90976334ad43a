#include "common/gather/gather.h"

#include <tbb/parallel_for.h>

namespace lightfarm {

std::vector<SubMatrixTask> GatherMethod::PlanStage(int stage, const GatherContext&,
                                                   const std::vector<SubMatrixTask>& tiles,
                                                   const StageArtifact&) const {
  std::vector<SubMatrixTask> tasks = tiles;
  for (SubMatrixTask& t : tasks) t.stage = uint32_t(stage);
  return tasks;
}

StageArtifact GatherMethod::Combine(int, const GatherContext&, const std::vector<TaskOutput>&) const {
  return {};
}

TaskOutput RunGatherTask(const GatherMethod& method, const GatherContext& ctx, const SubMatrixTask& task,
                         const StageArtifact& previous) {
  TaskOutput out = method.RunTask(ctx, task, previous);
  if (method.renders_film() || !ctx.matrix.has_extra_light() || int(task.stage) + 1 != method.stage_count()) return out;
  if (out.row_sums.size() != task.rows.size()) return out;  // the caller reports the mismatch
  ctx.matrix.caustic_map();  // traced once, before the rows gather from it
  std::vector<MatrixCounters> counters(task.rows.size());
  std::vector<RGBAccum> extra(task.rows.size());
  tbb::parallel_for(size_t(0), task.rows.size(),
                    [&](size_t i) { extra[i] = ctx.matrix.ExtraLight(task.rows[i], &counters[i]); });
  for (size_t i = 0; i < task.rows.size(); ++i) {
    out.row_sums[i].Add(extra[i]);
    out.counters.Add(counters[i]);
  }
  return out;
}

}  // namespace lightfarm
