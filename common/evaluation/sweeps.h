// What `lightfarm bench` sweeps: for each gather method, its quality knob over >= 5 settings,
// as the method declares it in its file (GatherMethodInfo::sweep).
#pragma once

#include <string>
#include <vector>

#include "common/util/bench_table.h"

namespace lightfarm {

struct SweepSetting {
  std::string label;                // e.g. "rows=50,columns=100"
  std::vector<std::string> params;  // --param entries: {"rows=50", "columns=100"}
};

struct MethodSweep {
  std::string method;
  std::vector<SweepSetting> settings;  // cheapest first
};

// The sweeps of `methods` (every method with a sweep when empty), in registry order. Throws OptionError for a name that is not registered or has no sweep entry.
std::vector<MethodSweep> SweepsFor(const std::vector<std::string>& methods);
// The same with `settings` ("a=1,b=2;a=2,b=4", cheapest first) in place of the table's line;
// it needs exactly one method. Throws OptionError otherwise or for an empty or malformed list
// (a setting's entries must be KEY=VALUE; the method checks the values when it runs).
std::vector<MethodSweep> SweepsFor(const std::vector<std::string>& methods,
                                   const std::string& settings);

// Registered methods that have a sweep entry (brute, the reference, has none).
std::vector<std::string> SweptMethodNames();

}  // namespace lightfarm
