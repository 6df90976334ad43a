// `lightcuts` (Walter 2005) against brute force: exact when error = 0 (every node that can
// contribute is refined to its leaves), close and much cheaper with the default 2% bound,
// deterministic whatever the thread count.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
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
  EXPECT_THROW(Render(scene, "lightcuts", {"floor=-0.1"}, 10, 4), OptionError);
  EXPECT_THROW(Render(scene, "lightcuts", {"floor=2"}, 10, 4), OptionError);
}

// The dark floor (lightcuts.cpp): a floor under a quad light, half of it in the shadow of a plate,
// a wall beside it. The shadowed half and the plate's underside get only what the wall and the
// lit floor bounce: small totals whose cuts the relative bound alone runs long.
std::string DarkFloorScene(const testing::TempDir& dir, const std::string& radiance) {
  return dir.Write("dark-floor-" + radiance + ".pbrt", R"(
Integrator "path" "integer maxdepth" [ 3 ]
Film "rgb" "integer xresolution" [ 24 ] "integer yresolution" [ 24 ] "string filename" [ "f.exr" ]
PixelFilter "box"
LookAt 0 1.5 6  0 0 0  0 1 0
Camera "perspective" "float fov" [ 60 ]
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ )" + radiance + " " + radiance + " " + radiance + R"( ] "bool twosided" true
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
    "point3 P" [ -0.5 4 -0.5  0.5 4 -0.5  0.5 4 0.5  -0.5 4 0.5 ]
AttributeEnd
Material "diffuse" "rgb reflectance" [ 0.3 0.3 0.3 ]
Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
  "point3 P" [ -4 0 -4  4 0 -4  4 0 4  -4 0 4 ]
Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
  "point3 P" [ -3 0 -4  -3 4 -4  -3 4 4  -3 0 4 ]
Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
  "point3 P" [ 0.3 2 -4  5 2 -4  5 2 4  0.3 2 4 ]
)");
}

TEST(Lightcuts, DarkFloorStopsDimRowsEarlyAndStaysClose) {
  testing::TempDir dir;
  const std::string scene = DarkFloorScene(dir, "4");
  RenderOutput brute = Render(scene, "brute", {}, 4000, 24);
  RenderOutput plain = Render(scene, "lightcuts", {"floor=0"}, 4000, 24);
  RenderOutput floored = Render(scene, "lightcuts", {"floor=0.5"}, 4000, 24);
  const nlohmann::json& stats = floored.stats["method_stats"];
  EXPECT_EQ(plain.stats["method_stats"]["floored"].get<double>(), 0.0);
  EXPECT_GT(stats["floored"].get<double>(), 0.0);
  EXPECT_GT(stats["pilot_rows"].get<double>(), 0.0);
  // The gather's cuts (the pilot's elements are on top of them).
  const double plain_cut = plain.stats["method_stats"]["cut_size"].get<double>();
  const double floored_cut = stats["cut_size"].get<double>();
  EXPECT_LT(floored_cut, 0.85 * plain_cut);
  const double plain_err = CompareImages(brute.image, plain.image).rel_l1;
  const double floored_err = CompareImages(brute.image, floored.image).rel_l1;
  std::printf("cut nodes: plain %.0f, floored %.0f (%.0f rows floored, %.0f capped); rel_l1 against brute "
              "force: plain %.5f, floored %.5f\n", plain_cut, floored_cut, stats["floored"].get<double>(),
              stats["cut_capped"].get<double>(), plain_err, floored_err);
  EXPECT_LT(floored_err, 0.03);
  EXPECT_LT(floored_err, plain_err + 0.005);
}

// The floor is a fraction of the image's own mean, never an absolute radiance: emitters four
// times as bright (a power of two, so every product and sum scales exactly) give the same cuts
// and an image exactly four times as bright.
TEST(Lightcuts, DarkFloorIsRelativeToTheImage) {
  testing::TempDir dir;
  RenderOutput one = Render(DarkFloorScene(dir, "4"), "lightcuts", {"floor=0.5"}, 4000, 24);
  RenderOutput four = Render(DarkFloorScene(dir, "16"), "lightcuts", {"floor=0.5"}, 4000, 24);
  EXPECT_GT(one.stats["method_stats"]["floored"].get<double>(), 0.0);
  EXPECT_EQ(Elements(one), Elements(four));
  EXPECT_EQ(one.stats["method_stats"]["floored"].get<double>(), four.stats["method_stats"]["floored"].get<double>());
  ASSERT_EQ(one.image.pixels.size(), four.image.pixels.size());
  for (size_t i = 0; i < one.image.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      ASSERT_NEAR(4 * one.image.pixels[i][c], four.image.pixels[i][c], 1e-5f * four.image.pixels[i][c])
          << "pixel " << i;
}

}  // namespace test_lightcuts
}  // namespace lightfarm
