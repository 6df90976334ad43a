// What each method declares in its own file (GatherMethodInfo) is usable as declared: every
// swept method has >= 5 settings its own factory accepts, cheapest first; the documented
// parameters for a target error are accepted too; `auto`'s measurements are sane numbers.
#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "common/evaluation/sweeps.h"
#include "common/gather/gather.h"
#include "common/render/method_chooser.h"
#include "common/render/render_options.h"
#include "common/util/error.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_method_info {

OptionMap Params(const std::vector<std::string>& list) { return OptionMap::Parse(list); }

TEST(MethodInfo, EverySweepSettingIsAcceptedByItsMethod) {
  std::set<std::string> names;
  for (const GatherMethodInfo& m : GatherMethods()) {
    EXPECT_TRUE(names.insert(m.name).second) << "two methods named " << m.name;
    ASSERT_TRUE(m.create) << m.name;
    EXPECT_EQ(m.create(OptionMap())->name(), m.name);
    if (m.name == "brute") {
      EXPECT_TRUE(m.sweep.empty());  // the reference is not swept
      continue;
    }
    const std::vector<MethodSweep> sweeps = SweepsFor({m.name});
    ASSERT_EQ(sweeps.size(), 1u) << m.name;
    EXPECT_GE(sweeps[0].settings.size(), 5u) << m.name;
    for (const SweepSetting& s : sweeps[0].settings) {
      if (m.name == "path") continue;  // spp=N is the bench's, not the method's (bench_run.cpp)
      OptionMap params = Params(s.params);
      EXPECT_NO_THROW(m.create(params)) << m.name << " " << s.label;
      EXPECT_NO_THROW(params.RejectUnused()) << m.name << " " << s.label;
    }
  }
}

TEST(MethodInfo, TargetErrorDefaultsAreUsable) {
  int with_target = 0;
  for (const GatherMethodInfo& m : GatherMethods()) {
    if (!m.params_for_target) continue;
    ++with_target;
    for (double target : {0.001, 0.02, 0.5}) {
      OptionMap params = Params(m.params_for_target(target));
      EXPECT_NO_THROW(m.create(params)) << m.name << " at " << target;
      EXPECT_NO_THROW(params.RejectUnused()) << m.name << " at " << target;
    }
  }
  EXPECT_GE(with_target, 3);
}

// What `auto` reads of the methods comes from the bench results compiled in: every method the
// surface bench swept is there at its defaults, each measurement is a sane number, and the
// settings a measurement carries are accepted by its method.
TEST(MethodInfo, AutosMeasurementsComeFromTheBenchResultsAndAreUsable) {
  const MethodChooser& chooser = MethodChooser::BuiltIn();
  std::set<std::string> surface;
  for (const MethodMeasurement& m : chooser.surface()) {
    surface.insert(m.method);
    EXPECT_TRUE(m.params.empty()) << m.method << " was measured on cornell-box at its defaults";
    EXPECT_GE(m.rel_l2, 0.0) << m.method;
    EXPECT_LT(m.rel_l2, 1.0) << m.method;
    EXPECT_GT(m.rays_per_pixel, 0.0) << m.method;
  }
  for (const char* name : {"lightcuts", "mrcs", "lightslice", "sparse-completion", "adaptive-completion"})
    EXPECT_TRUE(surface.count(name)) << name;
  ASSERT_FALSE(chooser.media().empty());
  for (const std::vector<MethodMeasurement>* list : {&chooser.surface(), &chooser.media()})
    for (const MethodMeasurement& m : *list) {
      OptionMap params = Params(m.params);
      EXPECT_NO_THROW(CreateGatherMethod(m.method, params)) << m.method << " " << m.setting;
      EXPECT_NO_THROW(params.RejectUnused()) << m.method << " " << m.setting;
    }
}

// A bench setting is a method's defaults when each value is the one the method reads in its
// absence: known from the method's own read (OptionMap::defaults_read), not from a copy.
TEST(MethodInfo, DefaultSettingsAreRecognisedFromTheMethodsOwnReads) {
  EXPECT_TRUE(IsMethodDefault("lightcuts", {}));
  EXPECT_TRUE(IsMethodDefault("lightcuts", {"error=0.02"}));
  EXPECT_TRUE(IsMethodDefault("lightcuts", {"error=0.020"}));
  EXPECT_FALSE(IsMethodDefault("lightcuts", {"error=0.1"}));
  EXPECT_TRUE(IsMethodDefault("mrcs", {"rows=300", "columns=600"}));  // columns = 2 · rows
  EXPECT_FALSE(IsMethodDefault("mrcs", {"rows=300", "columns=900"}));
  EXPECT_FALSE(IsMethodDefault("lightcuts", {"no_such_key=1"}));
  EXPECT_FALSE(IsMethodDefault("no-such-method", {}));
}

// The renderer-wide keys are read in one place (render_options.h) with their defaults, and each
// is documented in the README's option table (`--param key=...`, or a backticked `key` in the
// row of the key it qualifies).
TEST(RenderOptions, EveryRendererKeyHasADefaultAndIsDocumented) {
  const std::map<std::string, std::string> defaults = RenderOptionDefaults();
  EXPECT_GE(defaults.size(), 20u);
  std::ifstream in(testing::SourcePath("README.md"));
  ASSERT_TRUE(in) << "README.md";
  std::stringstream readme;
  readme << in.rdbuf();
  for (const auto& [key, value] : defaults) {
    EXPECT_FALSE(value.empty()) << key;
    const bool documented = readme.str().find("`--param " + key + "=") != std::string::npos ||
                            readme.str().find("`" + key + "`") != std::string::npos ||
                            readme.str().find("`" + key + "=") != std::string::npos;
    EXPECT_TRUE(documented) << "--param " << key << " is not in README.md's option table";
  }
}

// What a render reads is what it was given, and nothing it does not know passes silently.
TEST(RenderOptions, ValuesAreTypedAndCheckedAndTheSceneDecidesWhatIsAbsent) {
  OptionMap params = OptionMap::Parse({"clamp=0.05", "camera_paths=7", "segment_boundary=svm", "vrl_pieces=2"});
  const RenderOptions o = ReadRenderOptions(params, 9);
  EXPECT_DOUBLE_EQ(o.clamp, 0.05);
  EXPECT_FLOAT_EQ(o.matrix.clamp, 0.05f);
  ASSERT_TRUE(o.camera_paths.has_value());
  EXPECT_EQ(*o.camera_paths, 7);
  EXPECT_EQ(o.segment_slicing.boundary, SegmentBoundary::kSvm);
  EXPECT_EQ(o.vrl_pieces, 2);
  EXPECT_EQ(o.matrix.seed, 9u);
  EXPECT_NO_THROW(params.RejectUnused());
  // Absent keys the scene decides stay undecided here, and say so in the defaults.
  const OptionMap none;
  const RenderOptions d = ReadRenderOptions(none, 0);
  EXPECT_FALSE(d.camera_paths.has_value());
  EXPECT_EQ(d.matrix.caustic_photons, -1);
  EXPECT_EQ(d.matrix.media_compensation, -1);
  EXPECT_LT(d.matrix.sharp_roughness, 0.f);
  EXPECT_NE(none.defaults_read().at("caustic_photons").find("scene"), std::string::npos);
  for (const char* bad : {"clamp=2", "segment_boundary=svn", "media_lights=photons", "camera_paths=x",
                          "media_compensation=2"}) {
    OptionMap p = OptionMap::Parse({bad});
    EXPECT_THROW(ReadRenderOptions(p, 0), OptionError) << bad;
  }
  // A key no reader knows is an error naming it.
  OptionMap typo = OptionMap::Parse({"clamb=0.1"});
  ReadRenderOptions(typo, 0);
  try {
    typo.RejectUnused();
    ADD_FAILURE() << "clamb passed";
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("clamb"), std::string::npos);
  }
  // The method's keys: coverage for matrix methods, tiles for film methods, each rejected by the other.
  OptionMap film = OptionMap::Parse({"tile=8", "coverage=4"});
  const std::unique_ptr<GatherMethod> path = CreateGatherMethod("path", film);
  EXPECT_EQ(ReadMethodRenderOptions(film, *path).film_tile, 8);
  EXPECT_THROW(film.RejectUnused(), OptionError);
  OptionMap matrix = OptionMap::Parse({"coverage=4"});
  EXPECT_EQ(ReadMethodRenderOptions(matrix, *CreateGatherMethod("brute", matrix)).coverage, 4);
  EXPECT_NO_THROW(matrix.RejectUnused());
}

}  // namespace test_method_info
}  // namespace lightfarm
