// What each method declares in its own file (GatherMethodInfo) is usable as declared: every
// swept method has >= 5 settings its own factory accepts, cheapest first; the documented
// parameters for a target error are accepted too; `auto`'s measurements are sane numbers.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "common/evaluation/sweeps.h"
#include "common/gather/gather.h"
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

TEST(MethodInfo, TargetErrorDefaultsAndAutoMeasurementsAreUsable) {
  int with_target = 0, measured = 0;
  for (const GatherMethodInfo& m : GatherMethods()) {
    if (m.params_for_target) {
      ++with_target;
      for (double target : {0.001, 0.02, 0.5}) {
        OptionMap params = Params(m.params_for_target(target));
        EXPECT_NO_THROW(m.create(params)) << m.name << " at " << target;
        EXPECT_NO_THROW(params.RejectUnused()) << m.name << " at " << target;
      }
    }
    if (m.auto_surface_rel_l2 >= 0) {
      ++measured;
      EXPECT_LT(m.auto_surface_rel_l2, 1.0) << m.name;
      EXPECT_GT(m.auto_surface_rays_per_pixel, 0.0) << m.name;
    }
  }
  EXPECT_GE(with_target, 3);
  EXPECT_GE(measured, 4);
}

}  // namespace test_method_info
}  // namespace lightfarm
