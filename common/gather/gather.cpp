#include "common/gather/gather.h"

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

}  // namespace lightfarm
