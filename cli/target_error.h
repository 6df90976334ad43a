// `--target-error E` (render, submit): the method chooser's choice from the scene's bench results
// (common/render/method_chooser.h; where `lightfarm bench` caches them: cost_model.h), a
// prediction printed before the render, and the estimated and (when a cached brute-force
// reference exists) measured error after it.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "common/image/image.h"
#include "common/render/method_chooser.h"

namespace lightfarm::cli {

struct TargetErrorArgs {
  double target = 0;  // 0: off
  std::string bench_dir;
  std::string cache_dir;
  bool lights_given = false;  // --lights was on the command line: the choice keeps it
};

void AddTargetErrorOptions(CLI::App* cmd, TargetErrorArgs& args);

struct TargetErrorPlan {
  bool active = false;
  MethodChoice choice;
  std::vector<std::string> user_params;  // the render's --param before the choice was added
  std::vector<BenchRow> rows;
};

// Adds the chosen parameters to `settings` (a key the user set with --param is kept) and prints
// the choice and its predicted time on stderr. When the scene's bench results carry errors
// against the truth, the target is a truth rel_l1 and the choice includes the light count and
// spp (and the method, for `auto`). `--method auto` without --target-error uses the same model
// when it exists, at `--param target_error` (default 5% of the truth), and records why in
// settings->method_rule.
TargetErrorPlan ApplyTargetError(const TargetErrorArgs& args, const std::string& scene,
                                 RenderSettings* settings);

// Prints the estimated error and, with a cached reference for these settings, the measured one.
void ReportTargetError(const TargetErrorPlan& plan, const TargetErrorArgs& args,
                       const std::string& scene, const RenderSettings& settings,
                       const Image& image, double seconds);

// The default cache directory ($LIGHTFARM_CACHE/bench, $XDG_CACHE_HOME/lightfarm/bench,
// ~/.cache/lightfarm/bench).
std::string DefaultBenchCacheDir();

}  // namespace lightfarm::cli
