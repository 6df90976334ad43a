#include <functional>

#include "common/gather/methods.h"

namespace lightfarm {

namespace {

using Factory = std::function<std::unique_ptr<GatherMethod>(const OptionMap&)>;

// Explicit list (not static self-registration, which the linker may drop from a static library).
const std::vector<std::pair<std::string, Factory>>& Registry() {
  static const std::vector<std::pair<std::string, Factory>> registry = {
      {"brute", CreateBruteForceGather},
      {"mrcs", CreateMrcsGather},
      {"lightcuts", CreateLightcutsGather},
      {"sparse-completion", CreateSparseCompletionGather},
      {"adaptive-completion", CreateAdaptiveCompletionGather},
      {"lightslice", CreateLightSliceGather},
      {"path", CreatePathGather},
  };
  return registry;
}

}  // namespace

std::unique_ptr<GatherMethod> CreateGatherMethod(const std::string& name, const OptionMap& params) {
  for (const auto& [n, factory] : Registry())
    if (n == name) return factory(params);
  std::string known;
  for (const auto& [n, f] : Registry()) known += (known.empty() ? "" : ", ") + n;
  throw OptionError("unknown method \"" + name + "\" (available: " + known + ")");
}

std::vector<std::string> GatherMethodNames() {
  std::vector<std::string> names;
  for (const auto& [n, f] : Registry()) names.push_back(n);
  return names;
}

}  // namespace lightfarm
