// The clamp's path-traced compensation (common/matrix/clamp_compensation.cpp): in a closed
// emitting diffuse box (a furnace, radiance Le·Σ_{k≤D} ρ^k exactly) a large clamp visibly darkens
// the corners, and the compensation gives the light back; it is off unless asked for, changes
// nothing where nothing is clamped, and is deterministic. The element bound (bsdf_clamp) takes
// glossy peaks, never a Lambertian pair's light, and the compensation gives the peaks back.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <string>

#include "common/farm/render_job.h"
#include "tests/common/glossy_scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_clamp_compensation {

using testing::TempDir;

// A unit cube, every face a two-sided emitter of radiance 1 and reflectance rho, the camera at
// its centre looking at a corner.
std::string FurnaceBox(float rho, int maxdepth) {
  const std::string r = std::to_string(rho);
  return "Film \"rgb\" \"integer xresolution\" [16] \"integer yresolution\" [16]\nPixelFilter \"box\"\n"
         "Integrator \"path\" \"integer maxdepth\" [" + std::to_string(maxdepth) + "]\n"
         "LookAt 0.5 0.5 0.5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [100]\nWorldBegin\n"
         "AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n"
         "Material \"diffuse\" \"rgb reflectance\" [" + r + " " + r + " " + r + "]\n"
         "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1 1 0 0 1 0  0 0 1 1 0 1 1 1 1 0 1 1]\n"
         "  \"integer indices\" [0 1 2 0 2 3  4 6 5 4 7 6  0 4 5 0 5 1  3 2 6 3 6 7  0 3 7 0 7 4  1 5 6 1 6 2]\n";
}

double Mean(const Image& img) {
  double s = 0;
  for (const RGB& p : img.pixels) s += double(p.g);
  return s / double(img.pixels.size());
}

RenderOutput RenderBox(const std::string& path, int compensation) {
  RenderSettings s;
  s.method = "brute";
  s.spp = 4;
  s.lights = 4000;
  s.seed = 2;
  s.params = {"clamp=0.2", "clamp_compensation=" + std::to_string(compensation)};
  return RenderScene(path, s);
}

TEST(ClampCompensation, FurnaceBoxGetsTheClampedLightBack) {
  TempDir dir;
  const std::string path = dir.Write("box.pbrt", FurnaceBox(0.5f, 2));
  const double exact = 1 + 0.5 + 0.25;  // Le (1 + ρ + ρ²): emission, then two bounces
  const RenderOutput clamped = RenderBox(path, 0);
  const RenderOutput compensated = RenderBox(path, 16);
  const double lost = clamped.stats["clamp"]["energy_lost_fraction"].get<double>();
  EXPECT_GT(lost, 0.01);  // a large clamp in a small box: visible
  // The clamp takes ~2% of the image (4% of the light the matrix carries, which is 3/7 of it).
  EXPECT_LT(Mean(clamped.image), 0.99 * exact);
  EXPECT_NEAR(Mean(compensated.image), exact, 0.004 * exact);
  EXPECT_EQ(clamped.stats["clamp"]["compensation_paths"], 0);
  EXPECT_GT(compensated.stats["clamp"]["compensation_paths"].get<double>(), 0);
  // What the path tracer added back matches what the clamp took, within their noise (the VPLs'
  // own estimate of the loss is the noisy one: near-singular elements are why there is a clamp).
  const double after = compensated.stats["clamp"]["energy_lost_after_compensation"].get<double>();
  EXPECT_LT(std::abs(after), 0.25 * lost);
}

TEST(ClampCompensation, NothingChangesWithoutClampAndItIsDeterministic) {
  TempDir dir;
  const std::string path = dir.Write("box.pbrt", FurnaceBox(0.5f, 2));
  RenderSettings s;
  s.method = "brute";
  s.lights = 500;
  s.params = {"clamp=0", "clamp_compensation=4"};
  const RenderOutput off = RenderScene(path, s);
  s.params = {"clamp=0"};
  EXPECT_TRUE(testing::SameBits(off.image, RenderScene(path, s).image));
  EXPECT_EQ(off.stats["clamp"]["compensation_paths"], 0);

  s.params = {"clamp=0.2", "clamp_compensation=2"};
  RenderOutput one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = RenderScene(path, s);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = RenderScene(path, s);
  }
  EXPECT_TRUE(testing::SameBits(one.image, two.image));
  // Every method sees the same compensation: lightcuts' image moves by the same amount.
  s.method = "lightcuts";
  const RenderOutput lc = RenderScene(path, s);
  EXPECT_EQ(lc.stats["clamp"]["compensation_paths"], one.stats["clamp"]["compensation_paths"]);
}

// At the default bsdf_clamp = 1 the bound is the brightest a Lambertian pair can be: in the
// furnace, white walls at a clamp of 0.2, it binds nowhere and changes no bit.
TEST(ClampCompensation, TheElementBoundNeverBindsOnLambertianSurfaces) {
  TempDir dir;
  const std::string path = dir.Write("box.pbrt", FurnaceBox(1.f, 2));
  RenderSettings s;
  s.method = "brute";
  s.lights = 2000;
  s.params = {"clamp=0.2", "bsdf_clamp=0"};
  const RenderOutput off = RenderScene(path, s);
  s.params = {"clamp=0.2"};
  const RenderOutput on = RenderScene(path, s);
  EXPECT_TRUE(testing::SameBits(off.image, on.image));
  EXPECT_EQ(on.stats["clamp"]["bound_elements"], 0);
  EXPECT_EQ(on.stats["clamp"]["bound_lost_fraction"], 0.0);
  EXPECT_EQ(on.stats["clamp"]["compensation_paths"], off.stats["clamp"]["compensation_paths"]);
}

// A rough mirror (roughness 0.02, the split off so its VPLs and its receivers see every peak)
// under a small light: a tight bound (bsdf_clamp = 0.1) takes ~40% of the plane's light, and the
// compensation, which traces only each path's bound share, gives it back: the plane and the
// backdrop agree with the path tracer, and the traced energy with what the bound removed.
TEST(ClampCompensation, TheElementBoundTakesGlossyPeaksAndTheCompensationGivesThemBack) {
  TempDir dir;
  const std::string path = dir.Write("glossy.pbrt", testing::GlossyPlane(0.02f));
  auto render = [&](const std::string& method, int spp, std::vector<std::string> params) {
    RenderSettings s;
    s.method = method;
    s.spp = spp;
    s.lights = 2000;
    s.seed = 3;
    s.params = std::move(params);
    s.params.insert(s.params.end(), {"sharp_roughness=0", "caustic_photons=50000"});
    return RenderScene(path, s);
  };
  auto region = [](const Image& img, testing::PixelRect r) {
    double sum = 0;
    for (int y = r.y0; y < r.y0 + r.h; ++y)
      for (int x = r.x0; x < r.x0 + r.w; ++x) sum += double(img.at(x, y).Luminance());
    return sum / double(r.w * r.h);
  };
  const Image truth = render("path", 1024, {}).image;
  const RenderOutput bound = render("brute", 16, {"bsdf_clamp=0.1", "clamp_compensation=0"});
  const double lost = bound.stats["clamp"]["bound_lost_fraction"].get<double>();
  EXPECT_GT(bound.stats["clamp"]["bound_elements"].get<double>(), 100);
  EXPECT_GT(lost, 0.03);
  const double plane = region(truth, testing::kGlossyPlane);
  EXPECT_LT(region(bound.image, testing::kGlossyPlane), 0.8 * plane);
  const double backdrop = region(truth, testing::kGlossyBackdrop);
  const double blob = region(truth, testing::kGlossyBlob);
  // At 0.01 the bound also takes the light's own peak on the plane (~half the light in all),
  // which the compensation's emitter samples share with its BSDF samples by MIS.
  for (const std::string b : {"bsdf_clamp=0.1", "bsdf_clamp=0.01"}) {
    const RenderOutput compensated = render("brute", 16, {b, "clamp_compensation=16"});
    EXPECT_NEAR(region(compensated.image, testing::kGlossyPlane), plane, 0.05 * plane) << b;
    EXPECT_NEAR(region(compensated.image, testing::kGlossyBackdrop), backdrop, 0.04 * backdrop) << b;
    EXPECT_NEAR(region(compensated.image, testing::kGlossyBlob), blob, 0.05 * blob) << b;
    // The path tracer's estimate of what was removed against the VPLs' own (the noisier one).
    const double removed = compensated.stats["clamp"]["bound_lost_fraction"].get<double>();
    EXPECT_NEAR(compensated.stats["clamp"]["compensated_fraction"].get<double>(), removed, 0.2 * removed) << b;
  }
}

}  // namespace test_clamp_compensation
}  // namespace lightfarm
