// `lightcuts` (Walter 2005) against brute force: exact when error = 0 (every node that can
// contribute is refined to its leaves), close and much cheaper with the default 2% bound,
// deterministic whatever the thread count.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <string>

#include "common/render/render_job.h"
#include "common/image/metrics.h"
#include "common/util/error.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_lightcuts {

using testing::Elements;
using testing::ExpectImagesNear;

RenderOutput Render(const std::string& scene, const std::string& method,
                    std::vector<std::string> params, size_t lights = 2000, int res = 16) {
  RenderSettings s;
  s.method = method;
  s.width = s.height = res;
  s.lights = lights;
  s.seed = 3;
  s.params = std::move(params);
  return RenderScene(scene, s);
}


TEST(Lightcuts, ZeroErrorEqualsBruteForce) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {});
  RenderOutput exact = Render(scene, "lightcuts", {"error=0"});
  ExpectImagesNear(brute.image, exact.image, 1e-5f);
  EXPECT_EQ(exact.stats["method_stats"]["cut_capped"].get<double>(), 0.0);
  // Nodes whose bound is zero (facing away) are skipped, so it never costs more than brute.
  EXPECT_LE(Elements(exact), Elements(brute));
}

// Glossy receivers (conductors from mirror-like to rough) and glossy VPLs: the zero bounds of
// the microfacet lobes must not drop any contribution.
TEST(Lightcuts, ZeroErrorEqualsBruteForceWithGlossyMaterials) {
  const std::string scene = testing::SharedScene("veach-mis");
  RenderOutput brute = Render(scene, "brute", {}, 1500);
  RenderOutput exact = Render(scene, "lightcuts", {"error=0"}, 1500);
  ExpectImagesNear(brute.image, exact.image, 1e-5f);
}

TEST(Lightcuts, BoundedErrorIsAccurateAndCheap) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput brute = Render(scene, "brute", {});
  RenderOutput cut = Render(scene, "lightcuts", {"error=0.02"});
  ErrorMetrics m = CompareImages(brute.image, cut.image);
  EXPECT_LT(m.rel_l2, 0.03);
  EXPECT_GT(m.rel_l2, 0.0);  // an approximation, not a copy of brute force
  EXPECT_LT(double(Elements(cut)), 0.25 * double(Elements(brute)));
  // Mean cut size: stats / rows, well below the light count.
  const double rows = cut.stats["receivers"]["points"].get<double>();
  const double mean_cut = cut.stats["method_stats"]["cut_size"].get<double>() / rows;
  EXPECT_GT(mean_cut, 2.0);
  EXPECT_LT(mean_cut, 0.25 * cut.stats["lights"]["total"].get<double>());
  // A looser bound evaluates fewer elements.
  RenderOutput loose = Render(scene, "lightcuts", {"error=0.1"});
  EXPECT_LT(Elements(loose), Elements(cut));
}

TEST(Lightcuts, MaxCutLimitsTheCut) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput out = Render(scene, "lightcuts", {"error=0", "max_cut=3"}, 500, 8);
  const double rows = out.stats["receivers"]["points"].get<double>();
  EXPECT_LE(out.stats["method_stats"]["cut_size"].get<double>(), 3 * rows);
  EXPECT_GT(out.stats["method_stats"]["cut_capped"].get<double>(), 0.0);
}

TEST(Lightcuts, DeterministicAcrossThreadCounts) {
  const std::string scene = testing::SharedScene("cornell-box");
  RenderOutput two = Render(scene, "lightcuts", {"rows_per_slice=100"});
  RenderOutput one;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    one = Render(scene, "lightcuts", {"rows_per_slice=100"});
  }
  ASSERT_EQ(one.image.pixels.size(), two.image.pixels.size());
  for (size_t i = 0; i < one.image.pixels.size(); ++i)
    ASSERT_EQ(one.image.pixels[i], two.image.pixels[i]) << "pixel " << i;
  EXPECT_EQ(Elements(one), Elements(two));
  // Slicing changes the tasks, never a row's cut.
  RenderOutput sliced = Render(scene, "lightcuts", {"rows_per_slice=800"});
  for (size_t i = 0; i < one.image.pixels.size(); ++i)
    ASSERT_EQ(one.image.pixels[i], sliced.image.pixels[i]) << "pixel " << i;
}

// Lights at one point with one colour: every cluster's estimate is exact (Walter 2005, Eq. 2
// with identical material, geometry and visibility terms), so any cut gives the exact sum.
TEST(Lightcuts, CoincidentLightsAreExactAtAnyError) {
  testing::TempDir dir;
  std::string text =
      "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
      "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
      "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
      "WorldBegin\n";
  for (int i = 1; i <= 64; ++i)
    text += "LightSource \"point\" \"rgb I\" [" + std::to_string(0.1 * i) + " " +
            std::to_string(0.05 * i) + " " + std::to_string(0.02 * i) +
            "] \"point3 from\" [0.3 0.2 1]\n";
  text +=
      "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n"
      "  \"integer indices\" [0 1 2 0 2 3]\n";
  const std::string scene = dir.Write("scene.pbrt", text);
  RenderOutput brute = Render(scene, "brute", {}, 64, 8);
  RenderOutput cut = Render(scene, "lightcuts", {"error=0.5"}, 64, 8);
  ExpectImagesNear(brute.image, cut.image, 1e-4f);
  EXPECT_LT(Elements(cut), Elements(brute));
}

TEST(Lightcuts, RejectsInvalidParameters) {
  const std::string scene = testing::SharedScene("cornell-box");
  EXPECT_THROW(Render(scene, "lightcuts", {"error=2"}, 10, 4), OptionError);
  EXPECT_THROW(Render(scene, "lightcuts", {"max_cut=0"}, 10, 4), OptionError);
}

}  // namespace test_lightcuts
}  // namespace lightfarm
