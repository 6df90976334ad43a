// `sparse-completion` on slices that see no light at all and on light sets whose columns span 12
// orders of magnitude: finite, nonnegative images; exact (brute force) with full sampling; with
// sparse sampling bounded, with the bright region's energy and the light leaked into a black
// region held to what was measured.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "common/render/render_job.h"
#include "tests/stability/stability_util.h"

namespace lightfarm {
namespace test_sparse_completion_hard_cases {

using testing::TempDir;

// Seen from above: a floor cut into three bays by two walls. The left bay has an emitter of
// radiance 1e6, the middle one 1e-6, the right one none. Direct light only, so the right bay is
// exactly black and the other two differ by 12 orders of magnitude.
std::string Bays() {
  auto quad = [](const std::string& pts) {
    return "Shape \"trianglemesh\" \"point3 P\" [" + pts + "] \"integer indices\" [0 1 2 0 2 3]\n";
  };
  return "Film \"rgb\" \"integer xresolution\" [48] \"integer yresolution\" [16]\n"
         "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
         "LookAt 0 6 0  0 0 0  0 0 1\n"
         "Camera \"orthographic\" \"float screenwindow\" [-3 3 -1 1]\nWorldBegin\n"
         "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n" +
         quad("-3 0 -1  3 0 -1  3 0 1  -3 0 1") +            // floor, facing up
         quad("-1 0 -1  -1 3 -1  -1 3 1  -1 0 1") +          // wall x = -1
         quad("1 0 -1  1 3 -1  1 3 1  1 0 1") +              // wall x = 1
         "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1e6 1e6 1e6]\n" +
         quad("-1.6 2 -0.3  -1.6 2 0.3  -2.4 2 0.3  -2.4 2 -0.3") +
         "AttributeEnd\nAttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1e-6 1e-6 1e-6]\n" +
         quad("0.4 2 -0.3  0.4 2 0.3  -0.4 2 0.3  -0.4 2 -0.3") + "AttributeEnd\n";
}

RenderOutput Render(const std::string& scene, const std::string& method,
                    std::vector<std::string> params) {
  RenderSettings s;
  s.method = method;
  s.lights = 800;
  s.seed = 4;
  s.params = std::move(params);
  return RenderScene(scene, s);
}

// Sum of a column range of the image (one bay), in double.
double BaySum(const Image& image, int x0, int x1) {
  double sum = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = x0; x < x1; ++x) sum += double(image.at(x, y).g);
  return sum;
}

TEST(SparseCompletionHardCases, ZeroSlicesAndTwelveOrdersOfMagnitude) {
  TempDir dir;
  const std::string scene = dir.Write("bays.pbrt", Bays());
  const RenderOutput brute = Render(scene, "brute", {});
  // Camera x runs across the bays; which image side is which does not matter for the checks
  // below, but the bays must be where the test thinks: brightest at one end, black at the other.
  const Image& b = brute.image;
  ASSERT_EQ(b.width, 48);
  const double left = BaySum(b, 0, 14), middle = BaySum(b, 18, 30), right = BaySum(b, 34, 48);
  const bool flipped = right > left;
  const double bright = flipped ? right : left, dark = flipped ? left : right;
  ASSERT_GT(bright, 1e3);
  ASSERT_GT(middle, 0.0);
  ASSERT_LT(middle, bright * 1e-9);
  ASSERT_EQ(dark, 0.0);

  // Full sampling, no coarsening, every light its own column: brute force, bit for bit up to the
  // order of the double sums, in the 1e-6 bay as in the 1e6 one.
  const RenderOutput exact =
      Render(scene, "sparse-completion", {"rate=1", "merge_error=0", "global_cut=1000000"});
  testing::ExpectFiniteBounded(exact.image, 1e7f);
  for (size_t i = 0; i < b.pixels.size(); ++i)
    ASSERT_NEAR(exact.image.pixels[i].g, b.pixels[i].g, 1e-5f * b.pixels[i].g) << i;

  // Default sampling: finite, nonnegative, black where nothing is lit, the bright bay's energy
  // within a few percent.
  for (const std::vector<std::string>& params :
       {std::vector<std::string>{}, std::vector<std::string>{"rate=0.02", "rank=4"}}) {
    const RenderOutput approx = Render(scene, "sparse-completion", params);
    testing::ExpectFiniteBounded(approx.image, 1e7f);
    EXPECT_EQ(approx.stats["film"]["nan_samples"], 0);
    const Image& a = approx.image;
    const double a_bright = flipped ? BaySum(a, 34, 48) : BaySum(a, 0, 14);
    const double a_dark = flipped ? BaySum(a, 0, 14) : BaySum(a, 34, 48);
    float brute_max = 0, approx_max = 0;
    for (size_t i = 0; i < b.pixels.size(); ++i) {
      brute_max = std::max(brute_max, b.pixels[i].g);
      approx_max = std::max(approx_max, a.pixels[i].g);
    }
    std::printf("rate %s: bright %.4f dark/bright %.3g max/brute max %.3f\n",
                params.empty() ? "default" : params[0].c_str(), a_bright / bright, a_dark / bright,
                double(approx_max / brute_max));
    // Measured (seed 4): default rate keeps 85% of the bright bay and leaks 2.9% of it into the
    // black bay (slices straddle the walls and the completion extrapolates across them);
    // rate 0.02, rank 4 keeps 48% and leaks 9%. Bounded, but a limit of the method.
    const bool defaults = params.empty();
    EXPECT_LE(approx_max, 2.f * brute_max);
    EXPECT_NEAR(a_bright / bright, 1.0, defaults ? 0.25 : 0.6);
    EXPECT_LT(a_dark, (defaults ? 0.06 : 0.15) * bright);
  }
}

}  // namespace test_sparse_completion_hard_cases
}  // namespace lightfarm
