#include "cli/render_options.h"

#include <regex>

#include "common/util/error.h"

namespace lightfarm::cli {

void AddRenderOptions(CLI::App* cmd, RenderOptionArgs& a) {
  std::string methods;
  for (const std::string& m : GatherMethodNames()) methods += ", " + m;
  cmd->add_option("--method", a.method,
                  "Gather method: auto (default: picks by scene and target_error)" + methods);
  cmd->add_option("--resolution", a.resolution, "WxH (default: the scene's Film)");
  cmd->add_option("--filter", a.filter, "Override the scene's pixel filter")
      ->check(CLI::IsMember({"box", "triangle", "gaussian", "mitchell", "sinc"}));
  cmd->add_option("--spp", a.spp, "Camera samples per pixel (default: path the scene's Sampler pixelsamples, other methods 1)")
      ->check(CLI::Range(1, 4096));
  cmd->add_option("--lights", a.lights,
                  "Number of virtual lights (default " + std::to_string(kDefaultLights) +
                      ", or what --target-error or auto against a bench chooses)")->check(CLI::Range(1LL, 100000000LL));
  // Without the check CLI11 wraps a negative number into a huge unsigned seed.
  cmd->add_option("--seed", a.seed, "Random seed")->check(CLI::NonNegativeNumber);
  cmd->add_option("--param", a.params, "Method/renderer parameter KEY=VALUE (repeatable)");
  cmd->add_option("--passes", a.passes,
                  "Progressive reference: render N passes, each with its own seed, and average them "
                  "(with --until-noise or --time-limit: at most N; default " +
                      std::to_string(PassPlan::kDefaultMaxPasses) + ")")
      ->check(CLI::Range(1u, 1000000u));
  cmd->add_option("--until-noise", a.until_noise,
                  "Progressive reference: stop once the relative standard error of the image mean and of "
                  "its 90th-percentile pixel are below E (e.g. 0.01; at least 4 passes)")
      ->check(CLI::Range(1e-9, 10.0));
  cmd->add_option("--time-limit", a.time_limit_s,
                  "Progressive reference: stop after the pass running at S seconds")
      ->check(CLI::Range(1e-3, 1e9));
}

RenderSettings ToRenderSettings(const RenderOptionArgs& a) {
  RenderSettings s;
  // The farm's protocol reads an empty method as its default: say so instead of rendering brute.
  if (a.method.empty()) throw OptionError("--method needs a method name (e.g. brute)");
  s.method = a.method;
  if (!a.resolution.empty()) {
    std::smatch m;
    static const std::regex re(R"(^(\d{1,6})x(\d{1,6})$)");
    if (!std::regex_match(a.resolution, m, re))
      throw OptionError("--resolution expects WxH (e.g. 256x256), got \"" + a.resolution + "\"");
    s.width = std::stoi(m[1]);
    s.height = std::stoi(m[2]);
    if (s.width < 1 || s.height < 1 || s.width > 65536 || s.height > 65536)
      throw OptionError("--resolution " + a.resolution + " is out of range (1..65536 per axis)");
  }
  s.filter = a.filter;
  s.spp = a.spp;
  s.lights = a.lights > 0 ? size_t(a.lights) : kDefaultLights;
  s.seed = a.seed;
  s.params = a.params;
  s.progressive.until_noise = a.until_noise;
  s.progressive.time_limit_s = a.time_limit_s;
  s.progressive.passes = PassPlan::PassesFor(a.passes, s.progressive);
  return s;
}

}  // namespace lightfarm::cli
