// `--method auto`: the rule table (docs/rendering.md, "auto", shows the same table).
//
// Rows are tried in order; the first whose condition holds picks the first of its candidates the
// registry knows, or (no candidates) the cheapest of its measured methods within the target.
// A scene with media and no --param target_error is rendered the way that was closer to the truth
// at equal time (docs/methods/media-elements.md, "The defaults against path"): with a caustic
// path (a specular surface and indirect light: a volumetric caustic, which the path tracer's
// next-event estimation cannot reach through glass) by `adaptive-completion`, whose light paths
// carry it; else by `path` (on the cloud adaptive-completion is behind it at equal time at 128²
// and level at 256², docs/media-vs-path.md: the near lights' cost). Brute force, which the 2% target would
// pick, takes hours at a scene's own resolution. With a target, a scene with media chooses
// between `adaptive-completion` (Huo 2016's media method, the one measured on media scenes) and
// `brute`, exact: adaptive-completion when its worst measured rel_l2 there
// (GatherMethodInfo::auto_media_rel_l2, docs/media-methods.md) is within kSafety · target. The
// accuracy row picks, among the measured surface methods the registry knows, the one with the
// fewest shadow rays per pixel whose measured rel_l2 is at most
// kSafety · target (the measurements are one scene: keep a margin); without --param
// target_error the target is kDefaultTarget (2%).
//
// Surface measurements (GatherMethodInfo::auto_surface_*, in each method's file): cornell-box
// (the shared scenes' cornell-box, diffuse, area light + indirect VPLs), 64×64, 1 spp, seed 0,
// each method at its default parameters against brute
// force with the same lights, `lightfarm compare`; one run each on a loaded 2-core machine (rays
// are deterministic, times are not, so the cost is shadow rays per pixel). rel_l2 is the worst
// over 5000 and 20000 lights, rays per pixel are at 20000 lights (brute: 0.65 · lights).
// docs/rendering.md has the commands. Not measured: glossy/specular scenes (the same rule applies
// to them), light counts above 20000.
#include "common/gather/auto_method.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <vector>

#include "common/gather/gather.h"

namespace lightfarm {

namespace {

constexpr double kDefaultTarget = 0.02;  // rel_l2 when no target_error is given
constexpr double kSafety = 0.5;          // a method qualifies when measured rel_l2 <= 0.5·target
// At most this many lights: brute force, exact. Measured at 300 lights: brute casts 199 shadow
// rays per pixel in 1.0 s, lightcuts 90 in 1.8 s (its bounds cost more than the rays it saves);
// at 1000 lights brute casts 661 (2.9 s), lightcuts 127 (2.4 s).
constexpr size_t kBruteMaxLights = 300;

struct MeasuredMethod {
  std::string method;
  double rel_l2;           // worst measured relative L2 error against brute force
  double rays_per_pixel;   // shadow rays per pixel at 20000 lights
};

// What the methods of this build measured (GatherMethodInfo, in each method's file): on
// cornell-box (the protocol above; brute force, exact by definition, casts 13107 rays per pixel
// at 20000 lights) and in media.
std::vector<MeasuredMethod> Measured(bool media) {
  std::vector<MeasuredMethod> out;
  for (const GatherMethodInfo& m : GatherMethods()) {
    const double rel_l2 = media ? m.auto_media_rel_l2 : m.auto_surface_rel_l2;
    if (rel_l2 >= 0) out.push_back({m.name, rel_l2, media ? 0.0 : m.auto_surface_rays_per_pixel});
  }
  return out;
}

struct Rule {
  const char* name;
  // target_given: --param target_error was set (else the target is kDefaultTarget).
  std::function<bool(const Effects&, size_t lights, bool target_given)> applies;
  std::vector<std::string> candidates;  // first registered wins; empty: the accuracy choice
  bool media_measurements = false;  // the accuracy choice among Measured(media_measurements)
};

const std::vector<Rule>& Rules() {
  static const std::vector<Rule> rules = {
      {"media with caustics, equal time against the truth",
       [](const Effects& e, size_t, bool target) { return e.media && e.caustics() && !target; },
       {"adaptive-completion"}},
      {"media, equal time against the truth", [](const Effects& e, size_t, bool target) { return e.media && !target; },
       {"path"}},
      {"media", [](const Effects& e, size_t, bool) { return e.media; }, {}, true},
      {"few lights", [](const Effects&, size_t n, bool) { return n <= kBruteMaxLights; }, {"brute"}},
      {"accuracy", [](const Effects&, size_t, bool) { return true; }, {}, false},
  };
  return rules;
}

bool Registered(const std::string& name) {
  const std::vector<std::string> names = GatherMethodNames();
  return std::find(names.begin(), names.end(), name) != names.end();
}

double ReadTarget(const OptionMap& params) {
  if (!params.Has("target_error")) return kDefaultTarget;
  // GetDouble throws OptionError for a non-number or a value outside (0, 1].
  const double target = params.GetDouble("target_error", kDefaultTarget, 0.0, 1.0);
  if (!(target > 0)) throw OptionError("target_error must be > 0 (relative L2 error, e.g. 0.02)");
  return target;
}

}  // namespace

AutoMethodChoice ResolveAutoMethod(const Effects& effects, size_t lights, const OptionMap& params) {
  const double target = ReadTarget(params);
  for (const Rule& rule : Rules()) {
    if (!rule.applies(effects, lights, params.Has("target_error"))) continue;
    for (const std::string& c : rule.candidates)
      if (Registered(c)) return {c, rule.name};
    if (!rule.candidates.empty()) continue;
    // Accuracy: the cheapest measured method within the target (with the margin), else brute.
    const std::vector<MeasuredMethod> measured = Measured(rule.media_measurements);
    const MeasuredMethod* best = nullptr;
    for (const MeasuredMethod& m : measured)
      if (Registered(m.method) && m.rel_l2 <= kSafety * target &&
          (!best || m.rays_per_pixel < best->rays_per_pixel))
        best = &m;
    if (best) return {best->method, fmt::format("{} (target_error {})", rule.name, target)};
    return {"brute", fmt::format("{}: no measured method within target_error {}", rule.name, target)};
  }
  return {"brute", "fallback"};
}

std::string ResolveGatherMethodName(const std::string& requested, const Effects& effects,
                                    size_t lights, const OptionMap& params) {
  if (requested != kAutoMethod) return requested;
  AutoMethodChoice choice = ResolveAutoMethod(effects, lights, params);
  spdlog::info("method auto resolved to {} (rule: {})", choice.method, choice.rule);
  return choice.method;
}

void CheckGatherMethodOptions(const std::string& name, const OptionMap& params) {
  if (name == kAutoMethod) {
    ReadTarget(params);
    return;
  }
  CreateGatherMethod(name, params);
}

}  // namespace lightfarm
