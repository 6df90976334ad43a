// `--method auto` (MethodChooser::ForScene): the rule table resolves surface scenes by light count
// and accuracy target, media scenes without a target to `path` (with caustics:
// adaptive-completion), else to brute force unless the target allows adaptive-completion's
// measured error (the bench results compiled in), rejects a target that is not a number in
// (0, 1], and a render names the resolved method in its stats.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/render/render_job.h"
#include "common/render/method_chooser.h"
#include "common/gather/gather.h"
#include "common/util/error.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_auto_method {

// What ComputeEffects gives cornell-box: an area light, direct + indirect, diffuse only.
Effects SurfaceEffects() {
  Effects e;
  e.area_lights = true;
  e.diffuse = true;
  e.max_depth = 5;
  return e;
}

std::string Resolve(const Effects& e, size_t lights, std::vector<std::string> params = {}) {
  return MethodChooser::BuiltIn().ForScene(e, lights, OptionMap::Parse(params)).method;
}

TEST(AutoMethod, SurfaceScenesResolveByLightCountAndTarget) {
  const Effects e = SurfaceEffects();
  // Few lights: brute force is exact, and measured the faster up to brute_max_lights.
  const size_t few = MethodChooser::BuiltIn().brute_max_lights();
  ASSERT_GE(few, 100u) << "the few-lights bench should find brute force the faster at 100 lights";
  EXPECT_EQ(Resolve(e, 1), "brute");
  EXPECT_EQ(Resolve(e, few), "brute");
  EXPECT_EQ(Resolve(e, few + 1), "lightcuts");
  // The default target (2%): the cheapest method measured within half of it.
  EXPECT_EQ(Resolve(e, 20000), "lightcuts");
  EXPECT_EQ(Resolve(e, 1000000), "lightcuts");
  // A loose target buys the cheapest method; one tighter than any measured error, brute force.
  EXPECT_EQ(Resolve(e, 20000, {"target_error=0.1"}), "sparse-completion");
  // Between them the bench's cornell-box measurements decide: adaptive-completion (worst rel_l2
  // 0.013, 138 rays per pixel) is within half of 5% and cheaper than lightcuts (188).
  EXPECT_EQ(Resolve(e, 20000, {"target_error=0.05"}), "adaptive-completion");
  EXPECT_EQ(Resolve(e, 20000, {"target_error=0.0001"}), "brute");
  // Every answer is a method the registry can create.
  for (const char* target : {"target_error=0.0001", "target_error=0.01", "target_error=1"})
    EXPECT_NO_THROW(CreateGatherMethod(Resolve(e, 20000, {target}), OptionMap())) << target;
}

TEST(AutoMethod, MediaResolveToAdaptiveCompletionWithoutATargetElseByTheTarget) {
  Effects e = SurfaceEffects();
  e.media = true;
  // No target: adaptive-completion, at least level with the path tracer against the truth at
  // equal time on every media scene measured (docs/media-vs-path.md), whatever the light
  // count; the rule names the case, a volumetric caustic (light reaching the medium through
  // specular surfaces, which the path tracer's next-event estimation cannot connect through) or not.
  const MethodChooser& chooser = MethodChooser::BuiltIn();
  EXPECT_EQ(Resolve(e, 20000), "adaptive-completion");
  EXPECT_EQ(Resolve(e, 200), "adaptive-completion");
  EXPECT_EQ(chooser.ForScene(e, 20000, OptionMap()).rule, "media, equal time against the truth");
  Effects caustic = e;
  caustic.specular = true;
  EXPECT_EQ(Resolve(caustic, 20000), "adaptive-completion");
  EXPECT_EQ(chooser.ForScene(caustic, 20000, OptionMap()).rule, "media with caustics, equal time against the truth");
  caustic.max_depth = 1;  // direct light only: no caustic path
  EXPECT_EQ(chooser.ForScene(caustic, 20000, OptionMap()).rule, "media, equal time against the truth");
  EXPECT_EQ(Resolve(SurfaceEffects(), 20000), "lightcuts");  // surfaces keep the accuracy rule
  // With a target: the media scenes' bench results (docs/media-methods) measured
  // adaptive-completion at rho=0.1,sigma=0.01, worst rel_l2 0.021 (volumetric-caustic, 64k
  // lights); with the 0.5 margin it needs a target of at least 0.042, and the choice carries the
  // setting it was measured at.
  double measured = -1;
  for (const MethodMeasurement& m : chooser.media())
    if (m.method == "adaptive-completion") measured = m.rel_l2;
  ASSERT_GT(measured, 0.0);
  EXPECT_EQ(Resolve(e, 20000, {"target_error=0.02"}), "brute");
  EXPECT_EQ(Resolve(e, 20000, {"target_error=" + std::to_string(1.9 * measured)}), "brute");
  EXPECT_EQ(Resolve(e, 20000, {"target_error=" + std::to_string(2.1 * measured)}), "adaptive-completion");
  EXPECT_EQ(Resolve(e, 20000, {"target_error=0.15"}), "adaptive-completion");
  EXPECT_EQ(Resolve(e, 200, {"target_error=0.15"}), "adaptive-completion");  // media come first
  const MethodChoice media = chooser.ForScene(e, 20000, OptionMap::Parse({"target_error=0.15"}));
  EXPECT_EQ(media.basis, ChoiceBasis::kMeasured);
  EXPECT_EQ(media.params, (std::vector<std::string>{"rho=0.1", "sigma=0.01"}));
  const MethodChoice strict = chooser.ForScene(e, 20000, OptionMap::Parse({"target_error=0.02"}));
  EXPECT_FALSE(strict.reached);
  EXPECT_EQ(chooser.ForScene(e, 20000, OptionMap()).basis, ChoiceBasis::kSceneRule);
  EXPECT_NO_THROW(CreateGatherMethod(Resolve(e, 20000, {"target_error=0.15"}), OptionMap()));
}

TEST(AutoMethod, AMeasuredSettingReachesThePlanAndItsRule) {
  // A media scene with a target: adaptive-completion at the setting the bench measured it at,
  // added to the job's parameters (a key the user set wins) and named in the rule.
  RenderSettings s;
  s.method = "auto";
  s.width = s.height = 8;
  s.lights = 100;
  s.params = {"target_error=0.15"};
  const Plan plan = BuildPlan(testing::SharedScene("volumetric-caustic"), s, nullptr);
  EXPECT_EQ(plan.method->name(), "adaptive-completion");
  EXPECT_NE(plan.method_rule.find("rho=0.1,sigma=0.01"), std::string::npos) << plan.method_rule;
  s.params = {"target_error=0.15", "sigma=0.02"};
  const Plan user = BuildPlan(testing::SharedScene("volumetric-caustic"), s, nullptr);
  EXPECT_EQ(user.method->name(), "adaptive-completion");  // and sigma=0.02 was read, not rejected
}

TEST(AutoMethod, InvalidTargetIsAnOptionError) {
  for (const char* bad : {"target_error=fast", "target_error=0", "target_error=-0.1",
                          "target_error=2", "target_error="}) {
    EXPECT_THROW(Resolve(SurfaceEffects(), 20000, {bad}), OptionError) << bad;
    EXPECT_THROW(CheckGatherMethodOptions("auto", OptionMap::Parse({bad})), OptionError) << bad;
  }
  EXPECT_NO_THROW(CheckGatherMethodOptions("auto", OptionMap::Parse({"target_error=0.05"})));
  EXPECT_THROW(CheckGatherMethodOptions("no-such-method", OptionMap()), OptionError);
  // target_error is auto's parameter: a concrete method leaves it unused, which is an error.
  RenderSettings s;
  s.method = "brute";
  s.params = {"target_error=0.05"};
  EXPECT_THROW(BuildPlan(testing::SharedScene("cornell-box"), s, nullptr), OptionError);
}

TEST(AutoMethod, RenderStatsNameTheResolvedMethod) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderSettings s;
  s.method = "auto";
  s.width = s.height = 16;
  s.lights = 2000;
  s.seed = 1;
  {
    const Plan plan = BuildPlan(scene, s, nullptr);
    EXPECT_EQ(plan.method->name(), MethodChooser::BuiltIn().ForScene(plan.effects, s.lights, OptionMap()).method);
  }
  RenderOutput out = RenderScene(scene, s);
  EXPECT_EQ(out.stats["method"], "lightcuts");
  EXPECT_EQ(out.stats["method_requested"], "auto");
  EXPECT_EQ(out.stats["method_rule"], "accuracy (target_error 0.02)");
  EXPECT_GT(out.image.MeanLuminance(), 0);
  // A concrete method is its own request.
  s.method = "brute";
  s.lights = 50;
  RenderOutput brute = RenderScene(scene, s);
  EXPECT_EQ(brute.stats["method"], "brute");
  EXPECT_EQ(brute.stats["method_requested"], "brute");
  EXPECT_FALSE(brute.stats.contains("method_rule"));
}

// The few-lights threshold is read off a bench: the largest light count up to which brute force
// was the faster at every count measured.
TEST(AutoMethod, BruteForcesLightCountComesFromTheBench) {
  const auto row = [](size_t lights, const std::string& method, double time) {
    BenchRow r;
    r.scene = "s";
    r.lights = lights;
    r.method = method;
    r.setting = method == "brute" ? "reference" : "error=0.02";
    r.time_total_s = time;
    return r;
  };
  std::vector<BenchRow> rows = {row(100, "brute", 0.5), row(100, "lightcuts", 1.0), row(100, "lightcuts", 1.2),
                                row(300, "brute", 1.0), row(300, "lightcuts", 1.1), row(300, "lightcuts", 0.9),
                                row(300, "lightcuts", 1.3), row(1000, "brute", 3.0), row(1000, "lightcuts", 2.0),
                                row(3000, "brute", 4.0), row(3000, "lightcuts", 5.0)};
  // At 300 the median of lightcuts' three runs (1.1 s) is above brute's 1.0; at 1000 brute loses,
  // and a later win (3000, noise) does not count.
  EXPECT_EQ(BruteMaxLights(rows), 300u);
  rows[0].time_total_s = 1.5;  // brute loses at the smallest count: never brute
  EXPECT_EQ(BruteMaxLights(rows), 0u);
  EXPECT_EQ(BruteMaxLights({}), 0u);
  EXPECT_EQ(BruteMaxLights({row(100, "lightcuts", 1.0)}), 0u);  // no brute force measured
}

TEST(AutoMethod, TheCliDefaultsToAuto) {
  testing::TempDir dir;
  const std::string stats = dir.Path("img.json");
  const std::string cmd = std::string(LIGHTFARM_CLI_PATH) + " render " +
                          testing::SharedScene("cornell-box") +
                          " --resolution 8x8 --lights 100 --quiet --out " + dir.Path("img.exr") +
                          " --stats " + stats + " >/dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  std::ifstream f(stats);
  const nlohmann::json j = nlohmann::json::parse(f);
  EXPECT_EQ(j["method_requested"], "auto");
  EXPECT_EQ(j["method"], "brute");  // 100 lights: the few-lights row
  EXPECT_EQ(j["method_rule"], "few lights");
}

}  // namespace test_auto_method
}  // namespace lightfarm
