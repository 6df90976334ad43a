// The gather methods' declarations (GatherMethodInfo); each is defined in its own file in this
// folder, next to its algorithm.
#pragma once

#include "common/gather/gather.h"

namespace lightfarm {

GatherMethodInfo BruteForceMethod();
GatherMethodInfo MrcsMethod();
GatherMethodInfo LightcutsMethod();
GatherMethodInfo SparseCompletionMethod();
GatherMethodInfo LightSliceMethod();
GatherMethodInfo AdaptiveCompletionMethod();
GatherMethodInfo PathMethod();

}  // namespace lightfarm
