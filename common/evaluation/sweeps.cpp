#include "common/evaluation/sweeps.h"

#include <algorithm>
#include <sstream>
#include <utility>

#include "common/gather/gather.h"
#include "common/util/error.h"

namespace lightfarm {

namespace {

MethodSweep ParseSweep(const std::string& method, const std::string& line) {
  MethodSweep sweep;
  sweep.method = method;
  std::stringstream ss(line);
  std::string label;
  while (std::getline(ss, label, ';'))
    if (!label.empty()) sweep.settings.push_back({label, SplitParams(label)});
  return sweep;
}

}  // namespace

std::vector<std::string> SweptMethodNames() {
  std::vector<std::string> names;
  for (const GatherMethodInfo& m : GatherMethods())
    if (!m.sweep.empty()) names.push_back(m.name);
  return names;
}

std::vector<MethodSweep> SweepsFor(const std::vector<std::string>& methods) {
  const std::vector<std::string> wanted = methods.empty() ? SweptMethodNames() : methods;
  std::vector<MethodSweep> sweeps;
  for (const std::string& name : wanted) {
    if (name == "brute") continue;  // the reference: measured once per light set, not swept
    const GatherMethodInfo* m = FindGatherMethod(name);
    // Let the registry word the error (it lists the available methods).
    if (!m) CreateGatherMethod(name, OptionMap());
    if (m->sweep.empty())
      throw OptionError("method \"" + name + "\" has no bench sweep (GatherMethodInfo::sweep, in its file)");
    sweeps.push_back(ParseSweep(m->name, m->sweep));
  }
  return sweeps;
}

std::vector<MethodSweep> SweepsFor(const std::vector<std::string>& methods,
                                   const std::string& settings) {
  std::vector<MethodSweep> sweeps = SweepsFor(methods);
  if (settings.empty()) return sweeps;
  if (methods.size() != 1 || sweeps.size() != 1)
    throw OptionError("--settings needs exactly one swept method in --methods");
  MethodSweep custom = ParseSweep(sweeps[0].method, settings);
  if (custom.settings.empty()) throw OptionError("--settings: no setting in \"" + settings + "\"");
  for (const SweepSetting& s : custom.settings)
    for (const std::string& p : s.params)
      if (p.find('=') == std::string::npos || p.front() == '=')
        throw OptionError("--settings: \"" + p + "\" is not KEY=VALUE");
  return {custom};
}

}  // namespace lightfarm
