#include "cli/target_error.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "common/evaluation/cost_model.h"
#include "common/evaluation/reference.h"
#include "common/farm/program.h"
#include "common/image/image_io.h"
#include "common/image/metrics.h"
#include "common/render/method_chooser.h"
#include "common/util/options.h"
#include "common/util/error.h"

namespace lightfarm::cli {

namespace fs = std::filesystem;

std::string DefaultBenchCacheDir() {
  if (const char* env = std::getenv("LIGHTFARM_CACHE")) return std::string(env) + "/bench";
  if (const char* xdg = std::getenv("XDG_CACHE_HOME")) return std::string(xdg) + "/lightfarm/bench";
  if (const char* home = std::getenv("HOME")) return std::string(home) + "/.cache/lightfarm/bench";
  return ".lightfarm-cache/bench";
}

void AddTargetErrorOptions(CLI::App* cmd, TargetErrorArgs& a) {
  cmd->add_option("--target-error", a.target,
                  "Choose the method's parameters to reach this rel_l2 (e.g. 0.02) from the "
                  "scene's bench results, else documented defaults")
      ->check(FiniteRange(0.0, 1.0));
  cmd->add_option("--bench-dir", a.bench_dir,
                  "With --target-error: a `lightfarm bench` output dir (its results.csv)");
  cmd->add_option("--bench-cache", a.cache_dir,
                  "With --target-error: the bench cache (default: as `lightfarm bench`)");
}

namespace {

constexpr double kAutoTruthTarget = 0.05;  // `auto` with a truth model and no target_error

std::string Short(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// Adds the choice's parameters to the settings, except keys the user set with --param.
void AddChosenParams(const MethodChoice& c, const std::vector<std::string>& user_params, RenderSettings* s) {
  for (const std::string& p : c.params) {
    const std::string key = p.substr(0, p.find('='));
    bool user_set = false;
    for (const std::string& u : user_params) user_set = user_set || u.rfind(key + "=", 0) == 0;
    if (!user_set) s->params.push_back(p);
  }
}

// The error of `image` against `truth_file` when it has the image's size, printed; false if not.
bool PrintTruthError(const fs::path& truth_file, const Image& image) {
  if (!fs::exists(truth_file)) return false;
  const Image truth = ReadImage(truth_file.string());
  if (!truth.SameSize(image)) return false;
  const ErrorMetrics m = CompareImages(truth, image);
  std::fprintf(stderr, "; measured against the truth: rel_l1 %.4f, rel_l2 %.4f\n", m.rel_l1, m.rel_l2);
  return true;
}

// Applies a choice made against the truth: method (when auto), lights, spp, parameters.
void ApplyTruthChoice(const MethodChoice& c, const TargetErrorArgs& a, double target,
                      const std::vector<std::string>& user_params, RenderSettings* s) {
  if (s->method == kAutoMethod) {
    s->method = c.method;
    s->method_rule = "bench against the truth: the least predicted time to rel_l1 <= " + Short(target) + " (" +
                     c.method + (c.setting.empty() ? "" : " " + c.setting) +
                     (c.lights ? ", " + std::to_string(c.lights) + " lights" : "") + ", measured " +
                     Short(c.estimated_error) + ")" +
                     (c.reached ? "" : "; nothing reached it, the most accurate");
    // `auto`'s own parameter means nothing to the chosen method.
    std::vector<std::string> kept;
    for (const std::string& p : s->params)
      if (p.rfind("target_error=", 0) != 0) kept.push_back(p);
    s->params = kept;
  }
  if (c.lights > 0 && !a.lights_given) s->lights = c.lights;
  if (c.spp > 0 && s->spp == 0) s->spp = c.spp;
  AddChosenParams(c, user_params, s);
}

}  // namespace

TargetErrorPlan ApplyTargetError(const TargetErrorArgs& a, const std::string& scene,
                                 RenderSettings* s) {
  TargetErrorPlan plan;
  plan.user_params = s->params;
  const std::string cache = a.cache_dir.empty() ? DefaultBenchCacheDir() : a.cache_dir;
  fs::path csv = a.bench_dir.empty() ? CostModelPath(cache, scene) : fs::path(a.bench_dir) / "results.csv";
  if (!a.bench_dir.empty() && !fs::exists(csv))
    throw OptionError("--bench-dir " + a.bench_dir + " has no results.csv");
  const bool want_target = a.target > 0;
  if (!want_target && s->method != kAutoMethod) return plan;
  if (fs::exists(csv)) plan.rows = ReadBenchCsv(csv.string());
  if (!want_target) {
    // `auto` with a bench model against the truth: the same choice as --target-error.
    if (!HasTruth(plan.rows)) return plan;
    const double target = OptionMap::Parse(s->params).GetDouble("target_error", kAutoTruthTarget, 1e-6, 1.0);
    plan.choice = MethodChooser::BuiltIn().ForTarget(kAutoMethod, target, plan.rows, *s);
    ApplyTruthChoice(plan.choice, a, target, plan.user_params, s);
    std::fprintf(stderr, "auto: %s\n", s->method_rule.c_str());
    return plan;
  }
  plan.active = true;
  plan.choice = MethodChooser::BuiltIn().ForTarget(s->method, a.target, plan.rows, *s);
  if (plan.choice.basis == ChoiceBasis::kBenchAgainstTruth)
    ApplyTruthChoice(plan.choice, a, a.target, plan.user_params, s);
  else
    AddChosenParams(plan.choice, plan.user_params, s);
  std::fprintf(stderr, "target error %g (%s): %s %s%s, from %s; predicted time %s\n", a.target,
               plan.choice.metric.c_str(), s->method.c_str(), plan.choice.setting.c_str(),
               plan.choice.lights && s->method != "path" ? (", " + std::to_string(s->lights) + " lights").c_str() : "",
               plan.choice.source.c_str(),
               plan.choice.predicted_s >= 0
                   ? (std::to_string(plan.choice.predicted_s).substr(0, 6) + " s").c_str()
                   : "unknown (no bench measurement)");
  return plan;
}

void ReportTargetError(const TargetErrorPlan& plan, const TargetErrorArgs& a,
                       const std::string& scene, const RenderSettings& s, const Image& image,
                       double seconds) {
  if (!plan.active) return;
  std::string estimated = plan.choice.estimated_error >= 0
                              ? std::to_string(plan.choice.estimated_error).substr(0, 7)
                              : "unknown";
  std::fprintf(stderr, "target error %g: took %.2f s; estimated %s %s", a.target, seconds,
               plan.choice.metric.c_str(), estimated.c_str());
  // Against the truth the bench measured with (beside its cost model, or in --bench-dir).
  if (HasTruth(plan.rows)) {
    const fs::path truth_file = a.bench_dir.empty()
                                    ? TruthModelPath(a.cache_dir.empty() ? DefaultBenchCacheDir() : a.cache_dir, scene)
                                    : fs::path(a.bench_dir) / "truth.exr";
    if (PrintTruthError(truth_file, image)) return;
    std::fprintf(stderr, "; no truth of this image's size to measure against\n");
    return;
  }
  // A cached brute-force reference for exactly these lights and receivers (full image, or the
  // pixel subset the bench used).
  ReferenceRequest req;
  req.scene = scene;
  req.settings = s;
  req.settings.params = plan.user_params;
  req.cache_dir = a.cache_dir.empty() ? DefaultBenchCacheDir() : a.cache_dir;
  std::vector<size_t> subsets = {0};
  for (const BenchRow& r : plan.rows)
    if (r.reference.rfind("pixels:", 0) == 0) subsets.push_back(std::stoull(r.reference.substr(7)));
  for (size_t n : subsets) {
    req.pixels = n;
    BenchReference ref;
    if (LoadCachedReference(req, &ref) && ref.image.SameSize(image)) {
      ErrorMetrics m = CompareWithReference(ref, image);
      std::fprintf(stderr, "; measured rel_l2 %.4f, rel_l1 %.4f (%s)\n", m.rel_l2, m.rel_l1,
                   n ? ("on the bench's " + std::to_string(n) + " reference pixels").c_str()
                     : "full reference");
      return;
    }
  }
  std::fprintf(stderr, "; no cached reference to measure against\n");
}

}  // namespace lightfarm::cli
