// What each method declares in its own file (GatherMethodInfo) is usable as declared: every
// swept method has >= 5 settings its own factory accepts, cheapest first; the documented
// parameters for a target error are accepted too; `auto`'s measurements are sane numbers.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "common/evaluation/sweeps.h"
#include "common/gather/gather.h"
#include "common/render/method_chooser.h"
#include "common/util/error.h"

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

}  // namespace test_method_info
}  // namespace lightfarm
