// `--target-error E` for render and submit: pick a method's parameters from what a bench
// measured on the scene (its results.csv), else from documented defaults.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "common/evaluation/bench_run.h"

namespace lightfarm {

// Where `lightfarm bench` leaves a copy of a scene's results.csv: cache_dir/models/<hash of
// the scene's files>.csv.
std::filesystem::path CostModelPath(const std::string& cache_dir, const std::string& scene);
// And of the truth image that bench measured against (same name, .truth.exr).
std::filesystem::path TruthModelPath(const std::string& cache_dir, const std::string& scene);

struct TargetChoice {
  std::string method;               // the method (differs from the request when it was `auto`)
  size_t lights = 0;                // the light count to render with (0: keep the request's)
  int spp = 0;                      // camera samples per pixel (0: keep the request's)
  std::string metric = "rel_l2 against same-lights brute force";  // what estimated_error measures
  std::vector<std::string> params;  // --param entries to add
  std::string setting;              // the same, comma-joined
  double predicted_s = -1;          // < 0: no measurement to predict from
  double estimated_error = -1;      // median error (`metric`) the bench measured for the setting
  std::string source;               // what the choice is based on, for the user
};

// `rows`: a bench's results for this scene (may be empty). The bench's setting with the lowest
// median time whose median rel_l2 <= target, at the bench light count closest to `lights`;
// its time is scaled by the ratio of camera samples (width·height·spp). If no bench row reached
// the target, the most accurate one (source says so). Without rows: DefaultForTargetError.
// Throws OptionError for a method without a default and without bench rows.
TargetChoice ChooseForTargetError(const std::string& method, double target,
                                  const std::vector<BenchRow>& rows, const RenderSettings& settings);

// Whether a bench's rows carry errors against the truth.
bool HasTruth(const std::vector<BenchRow>& rows);

// Against the truth (rows with truth columns): among `method`'s settings at every bench light
// count (every method's, brute force and `path` included, when `method` is "auto"), the one with
// the lowest predicted time whose median truth rel_l1 <= target; else the most accurate (source
// says so). Time is scaled by the ratio of pixels; lights and spp are part of the choice.
// Throws OptionError when the rows have no truth or nothing of `method`.
TargetChoice ChooseByTruth(const std::string& method, double target, const std::vector<BenchRow>& rows,
                           const RenderSettings& settings);

// Documented defaults (docs/accuracy.md): lightcuts error=E; mrcs columns=12/E (rows = half,
// clamped to [50, 5000]); sparse-completion rate=0.002/E (clamped to [0.01, 0.5]).
TargetChoice DefaultForTargetError(const std::string& method, double target);

}  // namespace lightfarm
