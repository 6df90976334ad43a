// How a render is chosen, in one place: `--method auto` at plan time (the rule table on the
// scene's effects, and the methods' bench measurements built into the binary), `--target-error`
// and `auto` with a scene's own bench results (the CLI, before it submits), and the bench
// reports' time to an error (FastestWithin). A choice is a method, its settings and a typed
// basis; callers branch on the basis, never on text. docs/rendering.md ("auto") has the table.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "common/render/render_job.h"
#include "common/scene/effects.h"
#include "common/util/bench_table.h"
#include "common/util/options.h"

namespace lightfarm {

inline constexpr const char* kAutoMethod = "auto";

enum class ChoiceBasis {
  kRequested,          // the method the user named, at its own defaults
  kSceneRule,          // `auto`: a row of the rule table names the method for the scene's effects
  kMeasured,           // `auto`: the cheapest measured method within the target, else brute force
  kBenchAgainstTruth,  // the scene's own bench results against the truth
  kBenchAgainstBrute,  // the scene's own bench results against same-lights brute force
  kDocumentedDefault,  // the method's documented parameters for a target (no bench results)
};

struct MethodChoice {
  std::string method;               // a method the registry knows
  std::vector<std::string> params;  // --param entries the choice adds (a key the user set wins)
  std::string setting;              // the same, comma-joined
  size_t lights = 0;                // the light count to render with (0: keep the request's)
  int spp = 0;                      // camera samples per pixel (0: keep the request's)
  ChoiceBasis basis = ChoiceBasis::kRequested;
  // False when nothing measured reached the target: the most accurate setting (a bench), or
  // brute force (the rule table), was taken instead.
  bool reached = true;
  double target = 0;
  std::string metric;               // what `target` and `estimated_error` measure
  double estimated_error = -1;      // the measured median error of the choice (< 0: none)
  double predicted_s = -1;          // its time scaled to the request (< 0: no measurement)
  std::string rule;                 // the rule table's row (kSceneRule, kMeasured): logs, stats
  std::string source;               // what the choice rests on, for the user
};

// What the rule table knows of a method: its measured setting (the method's own defaults when
// the bench measured them, else its most accurate setting, which the choice then carries), the
// worst median rel_l2 against same-lights brute force over the scenes and light counts measured,
// and the shadow rays per pixel at the largest light count.
struct MethodMeasurement {
  std::string method, setting;
  std::vector<std::string> params;  // empty: the method's defaults
  double rel_l2 = 0;
  double rays_per_pixel = 0;
};

// The most lights at which brute force is measured the fastest: the largest light count of the
// rows (a bench of brute force and other methods at small light counts) up to which, at every
// count, brute force's median time is at most the fastest other method's. 0 when it never is.
size_t BruteMaxLights(const std::vector<BenchRow>& rows);

enum class ErrorAgainst { kBrute, kTruth };  // median rel_l2 vs brute, median rel_l1 vs the truth
struct SettingPick {
  const SettingSummary* summary = nullptr;  // nullptr: `accept` admitted nothing
  bool reached = false;                     // false: nothing reached the target; the most accurate
};
// Among the summaries `accept` admits, the fastest (median time) whose error is within
// `target`; else the most accurate. What `--target-error` and the bench reports both use.
SettingPick FastestWithin(const std::vector<SettingSummary>& summaries, ErrorAgainst against,
                          double target, const std::function<bool(const SettingSummary&)>& accept);

class MethodChooser {
 public:
  // Bench results of surface scenes, of media scenes, and of brute force against the others at
  // small light counts (results.csv rows).
  MethodChooser(const std::vector<BenchRow>& surface, const std::vector<BenchRow>& media,
                const std::vector<BenchRow>& few_lights);
  // The measurements built into this binary: docs/surface-methods/cornell-box and
  // docs/media-methods/*, the results.csv `scripts/report-accuracy.sh` writes, and
  // docs/surface-methods/few-lights (`scripts/report-few-lights.sh`), compiled in
  // (CMakeLists.txt), so the coordinator and every worker resolve a job alike.
  static const MethodChooser& BuiltIn();

  // `--method auto` at plan time, from the scene's effects, the light count and
  // `--param target_error` (read and marked used; OptionError when it is not in (0, 1]).
  // Deterministic: the coordinator and every worker resolve a job to the same choice.
  MethodChoice ForScene(const Effects& effects, size_t lights, const OptionMap& params) const;

  // From a scene's bench results (`rows`, possibly empty): against the truth when they carry it
  // (every method's settings, brute force and `path` included, when `method` is auto; lights and
  // spp are part of the choice), else the method's settings against same-lights brute force at
  // the bench light count nearest the request's, else the method's documented parameters.
  // Throws OptionError for a target outside (0, 1], for auto without results against the truth,
  // and for a method without a documented default or results.
  MethodChoice ForTarget(const std::string& method, double target, const std::vector<BenchRow>& rows,
                         const RenderSettings& settings) const;

  const std::vector<MethodMeasurement>& surface() const { return surface_; }
  const std::vector<MethodMeasurement>& media() const { return media_; }
  // Up to this many lights a surface scene renders with brute force (BruteMaxLights).
  size_t brute_max_lights() const { return brute_max_lights_; }

 private:
  std::vector<MethodMeasurement> surface_, media_;
  size_t brute_max_lights_ = 0;
};

// Whether bench rows carry errors against the truth.
bool HasTruth(const std::vector<BenchRow>& rows);

// `requested` itself unless it is "auto" (then the built-in chooser's method for the scene).
std::string ResolveGatherMethodName(const std::string& requested, const Effects& effects,
                                    size_t lights, const OptionMap& params);

// What can be checked before the scene is known (submit time, or before parsing): a concrete
// method is created with its parameters; "auto" checks target_error. Throws OptionError.
void CheckGatherMethodOptions(const std::string& name, const OptionMap& params);

// Whether `params` (a bench setting) are `method`'s own defaults: each key's value is the one
// the method reads when the key is absent (OptionMap::defaults_read).
bool IsMethodDefault(const std::string& method, const std::vector<std::string>& params);

}  // namespace lightfarm
