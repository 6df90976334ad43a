// Scale: a scene far from the origin renders like the same scene at the origin (ray offsets grow
// with the coordinates, so no self-shadowing acne), and lights of very different intensity sum
// without losing the dim ones (row sums in double, checked against a double-precision sum of the
// closed-form elements computed here).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "common/render/render_job.h"
#include "common/image/metrics.h"
#include "tests/stability/stability_util.h"

namespace lightfarm {
namespace test_scale {

using testing::MeanLuminance;
using testing::TempDir;

std::string P(double ox, double oy, double oz, double x, double y, double z) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g ", ox + x, oy + y, oz + z);
  return buf;
}

// A unit room (floor, ceiling, back and side walls), a block standing on the floor and a small
// area light under the ceiling, everything (camera included) shifted by (ox, oy, oz). Indirect
// light on: shadow rays leave every surface, including the corners and the block's base.
std::string Room(double ox, double oy, double oz) {
  auto p = [&](double x, double y, double z) { return P(ox, oy, oz, x, y, z); };
  auto quad = [&](const std::string& a, const std::string& b, const std::string& c,
                  const std::string& d) {
    return "Shape \"trianglemesh\" \"point3 P\" [" + a + b + c + d +
           "] \"integer indices\" [0 1 2 0 2 3]\n";
  };
  std::string s =
      "Integrator \"path\" \"integer maxdepth\" [3]\nPixelFilter \"box\"\n"
      "Film \"rgb\" \"integer xresolution\" [32] \"integer yresolution\" [32]\n"
      "LookAt " + p(0.5, 0.5, -1.4) + p(0.5, 0.5, 0.5) + "0 1 0\n"
      "Camera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
      "Material \"diffuse\" \"rgb reflectance\" [0.7 0.7 0.7]\n";
  s += quad(p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1));  // floor
  s += quad(p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0));  // ceiling
  s += quad(p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1));  // back
  s += "AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0.6 0.1 0.1]\n";
  s += quad(p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0));  // left
  s += "Material \"diffuse\" \"rgb reflectance\" [0.1 0.6 0.1]\n";
  s += quad(p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1));  // right
  s += "AttributeEnd\n";
  // The block: x in [0.2, 0.45], z in [0.4, 0.65], height 0.4, its base on the floor.
  s += "Shape \"trianglemesh\" \"point3 P\" [" + p(0.2, 0, 0.4) + p(0.45, 0, 0.4) +
       p(0.45, 0, 0.65) + p(0.2, 0, 0.65) + p(0.2, 0.4, 0.4) + p(0.45, 0.4, 0.4) +
       p(0.45, 0.4, 0.65) + p(0.2, 0.4, 0.65) +
       "] \"integer indices\" [4 5 6 4 6 7  0 1 5 0 5 4  1 2 6 1 6 5  2 3 7 2 7 6  3 0 4 3 4 7]\n";
  s += "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [20 20 20]\n";
  s += quad(p(0.6, 0.999, 0.4), p(0.6, 0.999, 0.6), p(0.4, 0.999, 0.6), p(0.4, 0.999, 0.4));
  s += "AttributeEnd\n";
  return s;
}

RenderOutput RenderRoom(const TempDir& dir, double ox, double oy, double oz) {
  RenderSettings s;
  s.method = "brute";
  s.lights = 2000;
  s.seed = 5;
  // Without the clamp's compensation: at 1e4 the ray offsets exceed the clamp distance, so
  // neither the clamp nor its compensation acts there, while both do near the origin; this test
  // is about precision, so only precision may differ between the two renders. Without camera
  // paths too: the light, seen almost edge-on as a strip about two pixels high, moves by float
  // rounding at 1e4 (~5e-4, 1.5% of a pixel); 257 paths per edge pixel measure that move (mean
  // ratio 0.986), while one sample per pixel at the same film position in both renders does not.
  s.params = {"clamp_compensation=0", "camera_paths=0"};
  return RenderScene(dir.Write("room.pbrt", Room(ox, oy, oz)), s);
}

TEST(Scale, SceneTranslatedFarFromTheOriginRendersLikeTheOriginal) {
  TempDir dir;
  const RenderOutput original = RenderRoom(dir, 0, 0, 0);
  const double original_mean = MeanLuminance(original.image);
  ASSERT_GT(original_mean, 0.0);
  for (double offset : {1e4, -1e4}) {
    const RenderOutput far = RenderRoom(dir, offset, 0.5 * offset, offset);
    testing::ExpectFiniteBounded(far.image, 1e4f);
    EXPECT_EQ(far.stats["film"]["nan_samples"], 0);
    // Acne darkens surfaces (their own shadow rays hit them); the mean would drop by the share
    // of pixels affected. Measured: the means agree within 0.3%, rel_l1 ≈ 0.02 (the receivers
    // and virtual lights move by float rounding at 1e4, ~1e-3 of the room).
    const ErrorMetrics m = CompareImages(original.image, far.image);
    EXPECT_NEAR(MeanLuminance(far.image) / original_mean, 1.0, 0.01) << offset;
    EXPECT_LT(m.rel_l1, 0.05) << offset;
    // No pixel goes dark where the original is lit.
    size_t dark = 0;
    for (size_t i = 0; i < original.image.pixels.size(); ++i)
      if (far.image.pixels[i].Luminance() < 0.5f * original.image.pixels[i].Luminance()) ++dark;
    EXPECT_LE(dark, original.image.pixels.size() / 100) << offset;
  }
}

// One light of intensity 1e5 and 1000 of 1e-3 over a Lambertian plane: the dim lights add ~1e-5
// of the bright one's contribution, below float's precision at that magnitude (a float sum drops
// every one of them), above the tolerance of the double sum.
TEST(Scale, BrightAndDimLightsSumWithoutLoss) {
  TempDir dir;
  const int dim_count = 1000;
  std::string lights = "LightSource \"point\" \"rgb I\" [1e5 1e5 1e5] \"point3 from\" [0.1 0.2 1]\n";
  for (int k = 0; k < dim_count; ++k) {
    const double a = 6.283185307179586 * k / dim_count;
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "LightSource \"point\" \"rgb I\" [1e-3 1e-3 1e-3] \"point3 from\" [%.6f %.6f 1]\n",
                  0.8 * std::cos(a), 0.8 * std::sin(a));
    lights += buf;
  }
  const std::string scene =
      "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\nPixelFilter \"box\"\n"
      "Integrator \"path\" \"integer maxdepth\" [1]\nLookAt 0 0 5  0 0 0  0 1 0\n"
      "Camera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\nWorldBegin\n" +
      lights +
      "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]"
      " \"integer indices\" [0 1 2 0 2 3]\n";
  RenderSettings settings;
  settings.lights = dim_count + 1;
  settings.seed = 1;
  PhaseTimes times;
  const Plan plan = BuildPlan(dir.Write("mix.pbrt", scene), settings, &times);
  ASSERT_EQ(plan.lights->size(), size_t(dim_count + 1));
  const GatherOutcome outcome = RunStagesLocally(plan, nullptr, &times);
  ASSERT_EQ(outcome.row_sums.size(), plan.receivers->points.size());
  ASSERT_GT(outcome.row_sums.size(), 0u);
  double worst = 0, worst_float = 0;
  for (size_t i = 0; i < outcome.row_sums.size(); ++i) {
    const ShadingPoint& sp = plan.receivers->points[i];
    // ρ/π · I · cos θ / d², each term and the sum in double.
    double exact = 0;
    float float_sum = 0;
    for (const VirtualLight& l : plan.lights->lights) {
      const double dx = double(l.p.x) - double(sp.p.x), dy = double(l.p.y) - double(sp.p.y),
                   dz = double(l.p.z) - double(sp.p.z);
      const double d2 = dx * dx + dy * dy + dz * dz;
      const double term = 0.5 / M_PI * double(l.power.g) * (dz / std::sqrt(d2)) / d2;
      exact += term;
      float_sum += float(term);
    }
    const double got = outcome.row_sums[i].g;
    worst = std::max(worst, std::abs(got - exact) / exact);
    worst_float = std::max(worst_float, std::abs(double(float_sum) - exact) / exact);
  }
  // Each element carries float rounding (~1e-7 relative); the sum adds nothing measurable.
  EXPECT_LT(worst, 1e-6);
  // And the test can tell: a float accumulator loses the dim lights' ~1e-5.
  EXPECT_GT(worst_float, 3e-6);
}

}  // namespace test_scale
}  // namespace lightfarm
