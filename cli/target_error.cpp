#include "cli/target_error.h"
#include "coordinator/cli_validators.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "common/bench/reference.h"
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

TargetErrorPlan ApplyTargetError(const TargetErrorArgs& a, const std::string& scene,
                                 RenderSettings* s) {
  TargetErrorPlan plan;
  if (!(a.target > 0)) return plan;
  plan.active = true;
  plan.user_params = s->params;
  const std::string cache = a.cache_dir.empty() ? DefaultBenchCacheDir() : a.cache_dir;
  fs::path csv = a.bench_dir.empty() ? CostModelPath(cache, scene) : fs::path(a.bench_dir) / "results.csv";
  if (!a.bench_dir.empty() && !fs::exists(csv))
    throw OptionError("--bench-dir " + a.bench_dir + " has no results.csv");
  if (fs::exists(csv)) plan.rows = ReadBenchCsv(csv.string());
  plan.choice = ChooseForTargetError(s->method, a.target, plan.rows, *s);
  for (const std::string& p : plan.choice.params) {
    const std::string key = p.substr(0, p.find('='));
    bool user_set = false;
    for (const std::string& u : plan.user_params) user_set = user_set || u.rfind(key + "=", 0) == 0;
    if (!user_set) s->params.push_back(p);
  }
  std::fprintf(stderr, "target error %g: %s %s, from %s; predicted time %s\n", a.target,
               s->method.c_str(), plan.choice.setting.c_str(), plan.choice.source.c_str(),
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
  std::fprintf(stderr, "target error %g: took %.2f s; estimated rel_l2 %s", a.target, seconds,
               estimated.c_str());
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
