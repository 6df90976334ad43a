// `lightfarm methods`: the renderer-wide parameters' defaults (render_options.h), then every
// gather method of this build with its own parameters' defaults (as the method reads them), its
// bench sweep, and what `auto` chooses by: the bench measurements compiled in
// (MethodChooser::BuiltIn, docs/surface-methods and docs/media-methods).
#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "common/gather/gather.h"
#include "common/render/method_chooser.h"
#include "common/render/render_options.h"

namespace lightfarm::cli {

namespace {

void PrintMeasurement(const char* where, const std::vector<MethodMeasurement>& list, const std::string& method) {
  for (const MethodMeasurement& m : list) {
    if (m.method != method) continue;
    std::printf("  auto, %s: worst rel_l2 %.4g at %s", where, m.rel_l2,
                m.params.empty() ? "its defaults" : m.setting.c_str());
    if (m.rays_per_pixel > 0) std::printf(", %.4g shadow rays per pixel", m.rays_per_pixel);
    std::printf("\n");
  }
}

std::string List(const std::map<std::string, std::string>& defaults) {
  std::string s;
  for (const auto& [key, value] : defaults) s += (s.empty() ? "" : ", ") + key + "=" + value;
  return s;
}

void PrintMethods() {
  std::printf("every method (--param)\n  parameters: %s\n", List(RenderOptionDefaults()).c_str());
  const MethodChooser& chooser = MethodChooser::BuiltIn();
  for (const GatherMethodInfo& info : GatherMethods()) {
    std::printf("%s\n", info.name.c_str());
    const OptionMap none;
    const std::unique_ptr<GatherMethod> method = info.create(none);
    // The keys whose meaning depends on the method (coverage paths, a film method's tiles).
    ReadMethodRenderOptions(none, *method);
    const std::string defaults = List(none.defaults_read());
    std::printf("  parameters: %s\n", defaults.empty() ? "(none)" : defaults.c_str());
    if (!info.sweep.empty()) std::printf("  bench sweep: %s\n", info.sweep.c_str());
    if (info.name == "brute")
      std::printf("  auto, surfaces: few lights: brute force up to %zu lights (docs/surface-methods/few-lights)\n",
                  chooser.brute_max_lights());
    PrintMeasurement("surfaces", chooser.surface(), info.name);
    PrintMeasurement("media", chooser.media(), info.name);
  }
}

}  // namespace

void AddMethodsCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "methods", "List the gather methods, their parameters' defaults and what `auto` measured of them");
  cmd->callback([] { PrintMethods(); });
}

}  // namespace lightfarm::cli
