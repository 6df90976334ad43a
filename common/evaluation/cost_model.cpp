#include "common/evaluation/cost_model.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/evaluation/bench_report.h"
#include "common/evaluation/reference.h"
#include "common/gather/gather.h"
#include "common/util/error.h"

namespace lightfarm {


std::filesystem::path CostModelPath(const std::string& cache_dir, const std::string& scene) {
  return std::filesystem::path(cache_dir) / "models" / (SceneFilesHash(scene) + ".csv");
}

std::filesystem::path TruthModelPath(const std::string& cache_dir, const std::string& scene) {
  return std::filesystem::path(cache_dir) / "models" / (SceneFilesHash(scene) + ".truth.exr");
}

TargetChoice DefaultForTargetError(const std::string& method, double target) {
  if (!(target > 0)) throw OptionError("--target-error must be positive");
  TargetChoice c;
  c.method = method;
  c.source = "documented default (no bench results for this scene)";
  const GatherMethodInfo* m = FindGatherMethod(method);
  if (m && m->params_for_target) {
    c.params = m->params_for_target(target);
  } else {
    throw OptionError("--target-error: no default for method \"" + method +
                      "\"; run `lightfarm bench` on the scene first (or pass --bench-dir)");
  }
  for (const std::string& p : c.params) c.setting += (c.setting.empty() ? "" : ",") + p;
  return c;
}

bool HasTruth(const std::vector<BenchRow>& rows) {
  for (const BenchRow& r : rows)
    if (std::isfinite(r.truth_rel_l1)) return true;
  return false;
}

TargetChoice ChooseByTruth(const std::string& method, double target, const std::vector<BenchRow>& rows,
                           const RenderSettings& s) {
  if (!(target > 0)) throw OptionError("--target-error must be positive");
  if (!HasTruth(rows)) throw OptionError("the bench results have no errors against the truth");
  const bool any_method = method == "auto";
  std::vector<BenchRow> mine;
  for (const BenchRow& r : rows)
    if ((any_method || r.method == method) && std::isfinite(r.truth_rel_l1)) mine.push_back(r);
  if (mine.empty()) throw OptionError("the bench results have nothing of method \"" + method + "\"");
  const BenchRow& any = mine.front();
  const int w = s.width > 0 ? s.width : any.width, h = s.height > 0 ? s.height : any.height;
  const double scale = double(w) * h / std::max(1.0, double(any.width) * any.height);
  const std::vector<SettingSummary> sums = Summarize(mine);
  const SettingSummary* pick = nullptr;
  for (const SettingSummary& m : sums)
    if (m.truth_rel_l1 <= target && (!pick || m.time_s < pick->time_s)) pick = &m;
  TargetChoice c;
  c.metric = "rel_l1 against the truth";
  c.source = "bench results against the truth (" + std::to_string(any.width) + "x" + std::to_string(any.height) + ")";
  if (!pick) {
    for (const SettingSummary& m : sums)
      if (!pick || m.truth_rel_l1 < pick->truth_rel_l1) pick = &m;
    c.source += "; no setting reached the target, using the most accurate one";
  }
  c.method = pick->method;
  c.lights = pick->method == "path" ? 0 : pick->lights;
  c.setting = pick->setting == "reference" ? "" : pick->setting;
  for (const std::string& p : SplitParams(c.setting)) {
    if (p.rfind("spp=", 0) == 0)
      c.spp = std::stoi(p.substr(4));
    else
      c.params.push_back(p);
  }
  if (c.spp == 0) {
    for (const BenchRow& r : mine)
      if (r.method == pick->method && r.setting == pick->setting) c.spp = r.spp;
  }
  c.estimated_error = pick->truth_rel_l1;
  c.predicted_s = pick->time_s * scale;
  return c;
}

TargetChoice ChooseForTargetError(const std::string& method, double target,
                                  const std::vector<BenchRow>& rows, const RenderSettings& s) {
  if (!(target > 0)) throw OptionError("--target-error must be positive");
  std::vector<BenchRow> mine;
  for (const BenchRow& r : rows)
    if (r.method == method) mine.push_back(r);
  if (mine.empty()) return DefaultForTargetError(method, target);
  // The bench light count closest to the request (in log scale).
  size_t lights = mine.front().lights;
  for (const BenchRow& r : mine)
    if (std::abs(std::log(double(r.lights) / double(s.lights))) <
        std::abs(std::log(double(lights) / double(s.lights))))
      lights = r.lights;
  const std::vector<SettingSummary> sums = Summarize(mine);
  const SettingSummary* pick = nullptr;
  for (const SettingSummary& m : sums)
    if (m.lights == lights && m.rel_l2 <= target && (!pick || m.time_s < pick->time_s)) pick = &m;
  TargetChoice c;
  c.method = method;
  const BenchRow& any = mine.front();
  c.source = "bench results (" + std::to_string(lights) + " lights, " + std::to_string(any.width) +
             "x" + std::to_string(any.height) + ", " + std::to_string(any.spp) + " spp)";
  if (!pick) {
    for (const SettingSummary& m : sums)
      if (m.lights == lights && (!pick || m.rel_l2 < pick->rel_l2)) pick = &m;
    c.source += "; no setting reached the target, using the most accurate one";
  }
  c.setting = pick->setting;
  c.params = SplitParams(pick->setting);
  c.estimated_error = pick->rel_l2;
  // Cost scales with the camera samples (receivers); lights enter through the bench count.
  const double bench_samples = double(any.width) * any.height * any.spp;
  const int w = s.width > 0 ? s.width : any.width, h = s.height > 0 ? s.height : any.height;
  const double samples = double(w) * h * std::max(1, s.spp);  // 0: the default, 1 sample
  c.predicted_s = pick->time_s * (bench_samples > 0 ? samples / bench_samples : 1.0);
  return c;
}

}  // namespace lightfarm
