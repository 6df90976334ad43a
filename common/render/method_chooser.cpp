// The rule table `auto` resolves by (docs/rendering.md, "auto", shows the same table).
//
// Rows are tried in order; the first whose condition holds picks the first of its candidates the
// registry knows, or (no candidates) the cheapest measured method within the target. A scene with
// media and no --param target_error is rendered by `adaptive-completion`, which was at least level
// with `path` against the truth at equal time on every media scene and size measured
// (docs/media-vs-path.md): far ahead with a caustic path (a specular surface and indirect light:
// a volumetric caustic, which the path tracer's next-event estimation cannot reach through glass,
// and the light paths carry), ahead on the cloud at 256² and level at 128² (behind there on
// rel_l2). The two rows say which case decided. Brute force, which the 2% target would pick,
// takes hours at a scene's own resolution. With a target, a scene with media chooses among
// the methods measured on the media scenes (docs/media-methods), else brute force, exact; a
// surface scene among those measured on cornell-box (docs/surface-methods), else brute force.
// Without media and with few lights, brute force: exact, and up to the light count the
// few-lights bench measured it the faster (docs/surface-methods/few-lights, BruteMaxLights).
// A method qualifies when its worst measured rel_l2 is at most kSafety · target (the
// measurements are few scenes: keep a margin); the cheapest in shadow rays per pixel wins.
// Without --param target_error the target is kDefaultTarget (2%).
#include "common/render/method_chooser.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>

#include "common/gather/gather.h"
#include "common/util/error.h"

namespace lightfarm {

// The bench results compiled in (CMakeLists.txt writes them from docs/*/results.csv), one
// results.csv per entry, null-terminated.
extern const char* const kSurfaceMeasurementsCsv[];
extern const char* const kMediaMeasurementsCsv[];
extern const char* const kFewLightsMeasurementsCsv[];

namespace {

constexpr double kDefaultTarget = 0.02;  // rel_l2 when no target_error is given
constexpr double kSafety = 0.5;          // a method qualifies when measured rel_l2 <= 0.5·target
// What a rule decides on.
struct RuleInput {
  const Effects& effects;
  size_t lights;
  bool target_given;        // --param target_error was set (else the target is kDefaultTarget)
  size_t brute_max_lights;  // MethodChooser::brute_max_lights
};

struct Rule {
  const char* name;
  std::function<bool(const RuleInput&)> applies;
  std::vector<std::string> candidates;  // first registered wins; empty: the measured choice
  bool media_measurements = false;      // the measured choice among the media measurements
};

const std::vector<Rule>& Rules() {
  static const std::vector<Rule> rules = {
      {"media with caustics, equal time against the truth",
       [](const RuleInput& in) { return in.effects.media && in.effects.caustics() && !in.target_given; },
       {"adaptive-completion"}},
      {"media, equal time against the truth",
       [](const RuleInput& in) { return in.effects.media && !in.target_given; }, {"adaptive-completion"}},
      {"media", [](const RuleInput& in) { return in.effects.media; }, {}, true},
      // Brute force is exact, and up to the measured light count also the fastest.
      {"few lights", [](const RuleInput& in) { return in.lights <= in.brute_max_lights; }, {"brute"}},
      {"accuracy", [](const RuleInput&) { return true; }, {}, false},
  };
  return rules;
}

bool Registered(const std::string& name) { return FindGatherMethod(name) != nullptr; }

double ReadAutoTarget(const OptionMap& params) {
  if (!params.Has("target_error")) return kDefaultTarget;
  // GetDouble throws OptionError for a non-number or a value outside (0, 1].
  const double target = params.GetDouble("target_error", kDefaultTarget, 0.0, 1.0);
  if (!(target > 0)) throw OptionError("target_error must be > 0 (relative L2 error, e.g. 0.02)");
  return target;
}

void CheckTarget(double target) {
  if (!(target > 0) || target > 1) throw OptionError("--target-error must be in (0, 1]");
}

std::string Join(const std::vector<std::string>& params) {
  std::string s;
  for (const std::string& p : params) s += (s.empty() ? "" : ",") + p;
  return s;
}

// Per method, the setting the rule table reads: its defaults when measured, else its most
// accurate. Brute force (the reference rows) is the fallback, not a candidate.
std::vector<MethodMeasurement> Measure(const std::vector<BenchRow>& rows) {
  // Medians over repeats per (scene, lights, method, setting); then the worst over scenes and
  // light counts, and the rays at the largest light count.
  std::map<std::string, std::vector<BenchRow>> by_scene;
  for (const BenchRow& r : rows)
    if (r.method != "brute" && std::isfinite(r.rel_l2)) by_scene[r.scene].push_back(r);
  struct Acc {
    double worst = 0;
    size_t lights = 0;
    double rays = 0;
  };
  std::map<std::pair<std::string, std::string>, Acc> acc;
  for (const auto& [scene, scene_rows] : by_scene)
    for (const SettingSummary& s : Summarize(scene_rows)) {
      Acc& a = acc[{s.method, s.setting}];
      a.worst = std::max(a.worst, s.rel_l2);
      if (s.lights > a.lights || (s.lights == a.lights && s.shadow_rays_per_pixel > a.rays)) {
        a.lights = s.lights;
        a.rays = s.shadow_rays_per_pixel;
      }
    }
  // A measurement at the method's defaults carries no parameters, and wins over any other.
  std::map<std::string, MethodMeasurement> chosen;
  for (const auto& [key, a] : acc) {
    const auto& [method, setting] = key;
    if (!Registered(method)) continue;
    const std::vector<std::string> params = SplitParams(setting);
    const bool is_default = IsMethodDefault(method, params);
    MethodMeasurement m{method, setting, is_default ? std::vector<std::string>{} : params, a.worst, a.rays};
    const auto it = chosen.find(method);
    if (it == chosen.end()) {
      chosen.emplace(method, std::move(m));
      continue;
    }
    const bool was_default = it->second.params.empty();
    if ((is_default && !was_default) || (is_default == was_default && m.rel_l2 < it->second.rel_l2))
      it->second = std::move(m);
  }
  std::vector<MethodMeasurement> out;
  for (const GatherMethodInfo& info : GatherMethods())  // registry order
    if (const auto it = chosen.find(info.name); it != chosen.end()) out.push_back(it->second);
  return out;
}

std::vector<BenchRow> ParseBuiltIn(const char* const* files, const char* name) {
  std::vector<BenchRow> rows;
  for (; *files; ++files) {
    std::istringstream in(*files);
    for (BenchRow& r : ParseBenchCsv(in, name)) rows.push_back(std::move(r));
  }
  return rows;
}

MethodChoice DocumentedDefault(const std::string& method, double target) {
  MethodChoice c;
  c.method = method;
  c.basis = ChoiceBasis::kDocumentedDefault;
  c.target = target;
  c.metric = "rel_l2 against same-lights brute force";
  c.source = "documented default (no bench results for this scene)";
  const GatherMethodInfo* m = FindGatherMethod(method);
  if (!m || !m->params_for_target)
    throw OptionError("--target-error: no default for method \"" + method +
                      "\"; run `lightfarm bench` on the scene first (or pass --bench-dir)");
  c.params = m->params_for_target(target);
  c.setting = Join(c.params);
  return c;
}

MethodChoice ByTruth(const std::string& method, double target, const std::vector<BenchRow>& rows,
                     const RenderSettings& s) {
  const bool any_method = method == kAutoMethod;
  std::vector<BenchRow> mine;
  for (const BenchRow& r : rows)
    if ((any_method || r.method == method) && std::isfinite(r.truth_rel_l1)) mine.push_back(r);
  if (mine.empty()) throw OptionError("the bench results have nothing of method \"" + method + "\"");
  const BenchRow& any = mine.front();
  const int w = s.width > 0 ? s.width : any.width, h = s.height > 0 ? s.height : any.height;
  const double scale = double(w) * h / std::max(1.0, double(any.width) * any.height);
  const std::vector<SettingSummary> sums = Summarize(mine);
  const SettingPick pick = FastestWithin(sums, ErrorAgainst::kTruth, target, [](const SettingSummary&) { return true; });
  MethodChoice c;
  c.basis = ChoiceBasis::kBenchAgainstTruth;
  c.target = target;
  c.reached = pick.reached;
  c.metric = "rel_l1 against the truth";
  c.source = "bench results against the truth (" + std::to_string(any.width) + "x" + std::to_string(any.height) + ")";
  if (!pick.reached) c.source += "; no setting reached the target, using the most accurate one";
  const SettingSummary& p = *pick.summary;
  c.method = p.method;
  c.lights = p.method == "path" ? 0 : p.lights;
  c.setting = p.setting == "reference" ? "" : p.setting;
  for (const std::string& param : SplitParams(c.setting)) {
    if (param.rfind("spp=", 0) == 0)
      c.spp = std::stoi(param.substr(4));
    else
      c.params.push_back(param);
  }
  if (c.spp == 0) {
    for (const BenchRow& r : mine)
      if (r.method == p.method && r.setting == p.setting) c.spp = r.spp;
  }
  c.estimated_error = p.truth_rel_l1;
  c.predicted_s = p.time_s * scale;
  return c;
}

MethodChoice ByBrute(const std::string& method, double target, const std::vector<BenchRow>& rows,
                     const RenderSettings& s) {
  std::vector<BenchRow> mine;
  for (const BenchRow& r : rows)
    if (r.method == method) mine.push_back(r);
  if (mine.empty()) return DocumentedDefault(method, target);
  // The bench light count closest to the request (in log scale).
  size_t lights = mine.front().lights;
  for (const BenchRow& r : mine)
    if (std::abs(std::log(double(r.lights) / double(s.lights))) <
        std::abs(std::log(double(lights) / double(s.lights))))
      lights = r.lights;
  const std::vector<SettingSummary> sums = Summarize(mine);
  const SettingPick pick = FastestWithin(sums, ErrorAgainst::kBrute, target,
                                         [&](const SettingSummary& m) { return m.lights == lights; });
  MethodChoice c;
  c.method = method;
  c.basis = ChoiceBasis::kBenchAgainstBrute;
  c.target = target;
  c.reached = pick.reached;
  c.metric = "rel_l2 against same-lights brute force";
  const BenchRow& any = mine.front();
  c.source = "bench results (" + std::to_string(lights) + " lights, " + std::to_string(any.width) +
             "x" + std::to_string(any.height) + ", " + std::to_string(any.spp) + " spp)";
  if (!pick.reached) c.source += "; no setting reached the target, using the most accurate one";
  c.setting = pick.summary->setting;
  c.params = SplitParams(pick.summary->setting);
  c.estimated_error = pick.summary->rel_l2;
  // Cost scales with the camera samples (receivers); lights enter through the bench count.
  const double bench_samples = double(any.width) * any.height * any.spp;
  const int w = s.width > 0 ? s.width : any.width, h = s.height > 0 ? s.height : any.height;
  const double samples = double(w) * h * std::max(1, s.spp);  // 0: the default, 1 sample
  c.predicted_s = pick.summary->time_s * (bench_samples > 0 ? samples / bench_samples : 1.0);
  return c;
}

}  // namespace

SettingPick FastestWithin(const std::vector<SettingSummary>& summaries, ErrorAgainst against,
                          double target, const std::function<bool(const SettingSummary&)>& accept) {
  const auto error = [&](const SettingSummary& s) { return against == ErrorAgainst::kTruth ? s.truth_rel_l1 : s.rel_l2; };
  SettingPick pick;
  for (const SettingSummary& s : summaries)
    if (accept(s) && error(s) <= target && (!pick.summary || s.time_s < pick.summary->time_s)) pick.summary = &s;
  pick.reached = pick.summary != nullptr;
  if (!pick.reached)
    for (const SettingSummary& s : summaries)
      if (accept(s) && std::isfinite(error(s)) && (!pick.summary || error(s) < error(*pick.summary))) pick.summary = &s;
  return pick;
}

bool HasTruth(const std::vector<BenchRow>& rows) {
  for (const BenchRow& r : rows)
    if (std::isfinite(r.truth_rel_l1)) return true;
  return false;
}

bool IsMethodDefault(const std::string& method, const std::vector<std::string>& params) {
  const GatherMethodInfo* info = FindGatherMethod(method);
  if (!info || !info->create) return false;
  const OptionMap none;
  info->create(none);
  const std::map<std::string, std::string>& defaults = none.defaults_read();
  for (const std::string& p : params) {
    const size_t eq = p.find('=');
    if (eq == std::string::npos) return false;
    const auto it = defaults.find(p.substr(0, eq));
    if (it == defaults.end()) return false;
    const std::string value = p.substr(eq + 1);
    if (value == it->second) continue;
    // Numbers compare by value ("0.10" is 0.1).
    char* end_a = nullptr;
    char* end_b = nullptr;
    const double a = std::strtod(value.c_str(), &end_a), b = std::strtod(it->second.c_str(), &end_b);
    if (value.empty() || *end_a != '\0' || *end_b != '\0' || a != b) return false;
  }
  return true;
}

size_t BruteMaxLights(const std::vector<BenchRow>& rows) {
  // Per light count, brute force's median time and the fastest other setting's.
  std::map<size_t, std::pair<double, double>> times;  // lights -> (brute, fastest other)
  for (const SettingSummary& s : Summarize(rows)) {
    auto& [brute, other] = times.try_emplace(s.lights, NAN, NAN).first->second;
    if (s.method == "brute")
      brute = s.time_s;
    else if (std::isnan(other) || s.time_s < other)
      other = s.time_s;
  }
  size_t most = 0;
  for (const auto& [lights, t] : times) {  // ascending light counts
    if (!(t.first <= t.second)) break;      // also when either is missing
    most = lights;
  }
  return most;
}

MethodChooser::MethodChooser(const std::vector<BenchRow>& surface, const std::vector<BenchRow>& media,
                             const std::vector<BenchRow>& few_lights)
    : surface_(Measure(surface)), media_(Measure(media)), brute_max_lights_(BruteMaxLights(few_lights)) {}

const MethodChooser& MethodChooser::BuiltIn() {
  static const MethodChooser chooser(ParseBuiltIn(kSurfaceMeasurementsCsv, "built-in surface measurements"),
                                     ParseBuiltIn(kMediaMeasurementsCsv, "built-in media measurements"),
                                     ParseBuiltIn(kFewLightsMeasurementsCsv, "built-in few-lights measurements"));
  return chooser;
}

MethodChoice MethodChooser::ForScene(const Effects& effects, size_t lights, const OptionMap& params) const {
  const double target = ReadAutoTarget(params);
  MethodChoice c;
  c.target = target;
  c.metric = "rel_l2 against same-lights brute force";
  for (const Rule& rule : Rules()) {
    if (!rule.applies(RuleInput{effects, lights, params.Has("target_error"), brute_max_lights_})) continue;
    for (const std::string& name : rule.candidates)
      if (Registered(name)) {
        c.method = name;
        c.basis = ChoiceBasis::kSceneRule;
        c.rule = rule.name;
        return c;
      }
    if (!rule.candidates.empty()) continue;
    // The cheapest measured method within the target (with the margin), else brute force.
    c.basis = ChoiceBasis::kMeasured;
    const MethodMeasurement* best = nullptr;
    for (const MethodMeasurement& m : rule.media_measurements ? media_ : surface_)
      if (m.rel_l2 <= kSafety * target && (!best || m.rays_per_pixel < best->rays_per_pixel)) best = &m;
    if (!best) {
      c.method = "brute";
      c.reached = false;
      c.rule = fmt::format("{}: no measured method within target_error {}", rule.name, target);
      return c;
    }
    c.method = best->method;
    c.params = best->params;
    c.setting = Join(c.params);
    c.estimated_error = best->rel_l2;
    c.rule = fmt::format("{} (target_error {})", rule.name, target);
    return c;
  }
  c.method = "brute";
  c.rule = "fallback";
  return c;
}

MethodChoice MethodChooser::ForTarget(const std::string& method, double target,
                                      const std::vector<BenchRow>& rows, const RenderSettings& settings) const {
  CheckTarget(target);
  if (HasTruth(rows)) return ByTruth(method, target, rows, settings);
  if (method == kAutoMethod)
    throw OptionError("--target-error with --method auto needs the scene's bench results against the truth "
                      "(run `lightfarm bench` on it) or a method");
  return ByBrute(method, target, rows, settings);
}

std::string ResolveGatherMethodName(const std::string& requested, const Effects& effects,
                                    size_t lights, const OptionMap& params) {
  if (requested != kAutoMethod) return requested;
  const MethodChoice choice = MethodChooser::BuiltIn().ForScene(effects, lights, params);
  spdlog::info("method auto resolved to {} (rule: {})", choice.method, choice.rule);
  return choice.method;
}

void CheckGatherMethodOptions(const std::string& name, const OptionMap& params) {
  if (name == kAutoMethod) {
    ReadAutoTarget(params);
    return;
  }
  CreateGatherMethod(name, params);
}

}  // namespace lightfarm
