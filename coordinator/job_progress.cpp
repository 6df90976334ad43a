#include "coordinator/job_progress.h"

#include <algorithm>
#include <cstdint>

namespace lightfarm {

double StageEtaSeconds(size_t tasks_done, size_t tasks_total, size_t done_at_stage_start, bool final_stage,
                       double stage_elapsed_s) {
  const size_t done_here = tasks_done - std::min(tasks_done, done_at_stage_start);
  if (!final_stage || done_here == 0) return -1;
  const double per_task = stage_elapsed_s / double(done_here);
  return per_task * double(tasks_total - tasks_done);
}

double PassesEtaSeconds(const PassPlan& plan, const PassAccumulator& acc, const NoiseEstimate& noise,
                        double running_pass_s) {
  const uint32_t done = acc.passes();
  double pass_s = 0;
  for (double t : acc.pass_seconds()) pass_s += t;
  const double mean_pass_s = pass_s / double(done);
  double left = double(plan.passes - std::min(done, plan.passes));
  if (plan.until_noise > 0) {
    const uint32_t to_target = PassesToReach(noise, done, plan.until_noise);
    const uint32_t floor_left = PassPlan::kMinNoisePasses - std::min(done, PassPlan::kMinNoisePasses);
    left = std::min(left, double(std::max(to_target == UINT32_MAX ? uint32_t(left) : to_target, floor_left)));
  }
  double eta = left * mean_pass_s;
  if (plan.time_limit_s > 0) eta = std::min(eta, std::max(0.0, plan.time_limit_s - pass_s) + mean_pass_s);
  return std::max(0.0, eta - running_pass_s);
}

}  // namespace lightfarm
