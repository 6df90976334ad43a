// Quasi-random particle paths (LightGenerationOptions::quasi_random_paths): every path's start is
// uniformly distributed (a randomly shifted Halton point), so the light set's expectation is
// that of independent paths; and their starts cover the emitters evenly, so what a light set
// carries varies less from seed to seed.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "common/lights/light_generation.h"
#include "common/scene/scene.h"
#include "common/scene/scene_description.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_light_paths {

// The flux of the first bounce: the luminance of every surface VPL one scattering event from the
// light, summed (an estimate of the light the emitters put on the scene's surfaces).
double FirstBounceFlux(const Scene& scene, uint64_t seed, bool quasi_random) {
  LightGenerationOptions opt;
  opt.target_lights = 1000;
  opt.max_depth = scene.hints().max_depth;
  opt.seed = seed;
  opt.quasi_random_paths = quasi_random;
  double sum = 0;
  for (const VirtualLight& l : GenerateLights(scene, opt).lights)
    if (l.kind == VirtualLightKind::kSurfaceVPL && l.depth == 1) sum += double(l.power.Luminance());
  return sum;
}

TEST(QuasiRandomPaths, SameExpectationLessSpreadBetweenSeeds) {
  const std::unique_ptr<Scene> scene = Scene::Build(ParseSceneFile(testing::ExampleCornellBox()), SceneBuildOptions{});
  const int n = 24;
  double mean[2] = {0, 0}, var[2] = {0, 0};
  for (int q = 0; q < 2; ++q) {
    std::vector<double> v;
    for (int s = 0; s < n; ++s) v.push_back(FirstBounceFlux(*scene, uint64_t(100 + s), q == 1));
    for (double x : v) mean[q] += x / n;
    for (double x : v) var[q] += (x - mean[q]) * (x - mean[q]) / (n - 1);
  }
  ASSERT_GT(mean[0], 0);
  const double se = std::sqrt(var[0] / n + var[1] / n);
  EXPECT_LT(std::abs(mean[1] - mean[0]), 4 * se) << "random " << mean[0] << ", halton " << mean[1];
  EXPECT_LT(std::sqrt(var[1]), 0.5 * std::sqrt(var[0]))
      << "standard deviation between seeds: random " << std::sqrt(var[0]) << ", halton " << std::sqrt(var[1]);
}

// The same seed gives the same light set, and the option changes it.
TEST(QuasiRandomPaths, DeterministicPerSeed) {
  const std::unique_ptr<Scene> scene = Scene::Build(ParseSceneFile(testing::ExampleCornellBox()), SceneBuildOptions{});
  EXPECT_EQ(FirstBounceFlux(*scene, 5, true), FirstBounceFlux(*scene, 5, true));
  EXPECT_NE(FirstBounceFlux(*scene, 5, true), FirstBounceFlux(*scene, 5, false));
}

}  // namespace test_light_paths
}  // namespace lightfarm
