// How long a job has left, from the scheduler's plain numbers (the status call puts them on the
// wire). Estimates, not promises: the running stage's pace so far, and for a progressive job its
// passes' mean time and the noise's 1/√N rate.
#pragma once

#include <cstddef>

#include "common/render/progressive.h"

namespace lightfarm {

// The final stage's time left: its time per finished task times the tasks left. Negative
// (unknown) before the final stage or before a task of it finished.
double StageEtaSeconds(size_t tasks_done, size_t tasks_total, size_t done_at_stage_start, bool final_stage,
                       double stage_elapsed_s);

// A progressive job's time left after `acc.passes()` finished passes (at least one): the passes
// left (to the most allowed, or to the noise target at its 1/√N rate, at least to the noise
// test's minimum) at their mean time, capped by the time limit, less the running pass's time.
double PassesEtaSeconds(const PassPlan& plan, const PassAccumulator& acc, const NoiseEstimate& noise,
                        double running_pass_s);

}  // namespace lightfarm
