// The render options `render` and `submit` share (DESIGN.md contract), parsed into RenderSettings.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "common/render/render_job.h"

namespace lightfarm::cli {

struct RenderOptionArgs {
  std::string method = "auto";
  std::string resolution;
  std::string filter;
  int spp = 0;  // 0: the method's default (path: the scene's pixelsamples, others: 1)
  long long lights = 0;  // 0: not given (kDefaultLights, or a --target-error / auto choice)
  unsigned long long seed = 0;
  std::vector<std::string> params;
  // A progressive job (progressive.h): 0 / 0 / 0 is one ordinary pass.
  unsigned passes = 0;
  double until_noise = 0;
  double time_limit_s = 0;
};

void AddRenderOptions(CLI::App* cmd, RenderOptionArgs& args);
RenderSettings ToRenderSettings(const RenderOptionArgs& args);  // throws OptionError

}  // namespace lightfarm::cli
