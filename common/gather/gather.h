// The interface every many-light method implements: given a sub-matrix (a set of receiver rows
// against the light set), return each row's RGB sum over all columns, plus what it cost. One
// method, one file (mitsuba-style), found by name in the registry (registry.cpp), so that the
// farm can distribute any of them. Nothing here knows about networking.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/matrix/lighting_matrix.h"
#include "common/util/options.h"

namespace lightfarm {

struct SubMatrixTask {
  uint32_t task_id = 0;
  std::vector<uint32_t> rows;  // receiver (shading point) indices
  uint64_t seed = 0;           // job seed; methods derive their randomness from (seed, task, ...)
};

struct GatherResult {
  std::vector<RGBAccum> row_sums;  // one per task row, same order
  MatrixCounters counters;
  std::map<std::string, double> stats;  // method-specific numbers (e.g. "clusters")
};

class GatherMethod {
 public:
  virtual ~GatherMethod() = default;
  virtual std::string name() const = 0;
  // Must be deterministic for a given task, whatever the thread count.
  virtual GatherResult Run(const LightingMatrix& matrix, const SubMatrixTask& task) const = 0;
};

// Creates a method by name, reading its parameters from `params` (marking them used).
// Throws OptionError for an unknown method or an invalid parameter value.
std::unique_ptr<GatherMethod> CreateGatherMethod(const std::string& name, const OptionMap& params);
std::vector<std::string> GatherMethodNames();

}  // namespace lightfarm
