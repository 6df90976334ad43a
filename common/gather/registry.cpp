#include <algorithm>

#include "common/gather/methods.h"

namespace lightfarm {

// Explicit list (not static self-registration, which the linker may drop from a static library).
// The order is the bench's and the reports' order of methods.
const std::vector<GatherMethodInfo>& GatherMethods() {
  static const std::vector<GatherMethodInfo> methods = {
      BruteForceMethod(), MrcsMethod(),       LightcutsMethod(),         SparseCompletionMethod(),
      LightSliceMethod(), AdaptiveCompletionMethod(), PathMethod(),
  };
  return methods;
}

const GatherMethodInfo* FindGatherMethod(const std::string& name) {
  const std::vector<GatherMethodInfo>& all = GatherMethods();
  auto it = std::find_if(all.begin(), all.end(), [&](const GatherMethodInfo& m) { return m.name == name; });
  return it == all.end() ? nullptr : &*it;
}

std::unique_ptr<GatherMethod> CreateGatherMethod(const std::string& name, const OptionMap& params) {
  if (const GatherMethodInfo* m = FindGatherMethod(name)) return m->create(params);
  std::string known;
  for (const GatherMethodInfo& m : GatherMethods()) known += (known.empty() ? "" : ", ") + m.name;
  throw OptionError("unknown method \"" + name + "\" (available: " + known + ")");
}

std::vector<std::string> GatherMethodNames() {
  std::vector<std::string> names;
  for (const GatherMethodInfo& m : GatherMethods()) names.push_back(m.name);
  return names;
}

}  // namespace lightfarm
