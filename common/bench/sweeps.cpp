#include "common/bench/sweeps.h"

#include <algorithm>
#include <sstream>
#include <utility>

#include "common/gather/gather.h"
#include "common/util/error.h"

namespace lightfarm {

namespace {

// One line per method: settings separated by ';', each a comma-separated --param list, from
// the cheapest to the most accurate. Adding a method to the bench is adding its line here; a
// line whose method is not registered in this build is ignored.
const std::vector<std::pair<std::string, std::string>>& SweepTable() {
  static const std::vector<std::pair<std::string, std::string>> table = {
      // Hašan 2007 uses rows:columns of 1:2 and 1:3 (Fig. 6).
      {"mrcs", "rows=25,columns=50;rows=50,columns=100;rows=50,columns=150;rows=100,columns=200;"
               "rows=100,columns=300;rows=200,columns=400;rows=300,columns=600;rows=300,columns=900"},
      // Walter 2005: the per-receiver relative error bound (2% in the paper).
      {"lightcuts", "error=0.2;error=0.1;error=0.05;error=0.02;error=0.01;error=0.005"},
      // Huo 2015: sampling rate 1-20% (10% default).
      {"sparse-completion", "rate=0.01;rate=0.02;rate=0.05;rate=0.1;rate=0.2"},
      // Ou & Pellacini 2011: global clusters and the per-slice refinement's clusters (2:3).
      {"lightslice", "global_clusters=50,local_clusters=75;global_clusters=100,local_clusters=150;"
                     "global_clusters=200,local_clusters=300;global_clusters=400,local_clusters=600;"
                     "global_clusters=800,local_clusters=1200"},
      // Huo 2016: sampling ratio rho and the error threshold sigma.
      {"adaptive-completion", "rho=0.05,sigma=0.05;rho=0.1,sigma=0.02;rho=0.1,sigma=0.01;"
                              "rho=0.1,sigma=0.005;rho=0.2,sigma=0.002"},
      // The path tracer: what a user would run instead. Its knob is the samples per pixel (a
      // sweep's spp=N sets them; bench_run.cpp); it uses no virtual lights.
      {"path", "spp=4;spp=16;spp=64;spp=256;spp=1024"},
  };
  return table;
}

MethodSweep ParseSweep(const std::string& method, const std::string& line) {
  MethodSweep sweep;
  sweep.method = method;
  std::stringstream ss(line);
  std::string label;
  while (std::getline(ss, label, ';'))
    if (!label.empty()) sweep.settings.push_back({label, SplitParams(label)});
  return sweep;
}

bool IsRegistered(const std::string& name) {
  const std::vector<std::string> names = GatherMethodNames();
  return std::find(names.begin(), names.end(), name) != names.end();
}

}  // namespace

std::vector<std::string> SplitParams(const std::string& label) {
  std::vector<std::string> out;
  std::stringstream ss(label);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::vector<std::string> SweptMethodNames() {
  std::vector<std::string> names;
  for (const auto& [method, line] : SweepTable())
    if (IsRegistered(method)) names.push_back(method);
  return names;
}

std::vector<MethodSweep> SweepsFor(const std::vector<std::string>& methods) {
  const std::vector<std::string> wanted = methods.empty() ? SweptMethodNames() : methods;
  std::vector<MethodSweep> sweeps;
  for (const std::string& name : wanted) {
    if (name == "brute") continue;  // the reference: measured once per light set, not swept
    if (!IsRegistered(name)) {
      // Let the registry word the error (it lists the available methods).
      CreateGatherMethod(name, OptionMap());
    }
    auto it = std::find_if(SweepTable().begin(), SweepTable().end(),
                           [&](const auto& entry) { return entry.first == name; });
    if (it == SweepTable().end())
      throw OptionError("method \"" + name + "\" has no bench sweep (add a line to common/bench/sweeps.cpp)");
    sweeps.push_back(ParseSweep(it->first, it->second));
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
