// Factories of the gather methods; each is defined in its own file in this folder.
#pragma once

#include <memory>

#include "common/gather/gather.h"

namespace lightfarm {

std::unique_ptr<GatherMethod> CreateBruteForceGather(const OptionMap& params);
std::unique_ptr<GatherMethod> CreateMrcsGather(const OptionMap& params);
std::unique_ptr<GatherMethod> CreateLightcutsGather(const OptionMap& params);
std::unique_ptr<GatherMethod> CreateSparseCompletionGather(const OptionMap& params);
std::unique_ptr<GatherMethod> CreateAdaptiveCompletionGather(const OptionMap& params);
std::unique_ptr<GatherMethod> CreateLightSliceGather(const OptionMap& params);
std::unique_ptr<GatherMethod> CreatePathGather(const OptionMap& params);

}  // namespace lightfarm
