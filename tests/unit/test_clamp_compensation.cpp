// The clamp's path-traced compensation (common/matrix/clamp_compensation.cpp): in a closed
// emitting diffuse box (a furnace, radiance Le·Σ_{k≤D} ρ^k exactly) a large clamp visibly darkens
// the corners, and the compensation gives the light back; it is off unless asked for, changes
// nothing where nothing is clamped, and is deterministic. The element bound (bsdf_clamp) takes
// glossy peaks, never a Lambertian pair's light, and the compensation gives the peaks back.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <string>
#include <vector>

#include "common/evaluation/clamp_probe.h"
#include "common/render/render_job.h"
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

// The clamp's expected loss in the furnace, in closed form. Every face emits Le = 1 and reflects
// ρ, so the VPLs of depth 0 and 1 (all a camera hit may connect to at maxdepth 2) sit uniformly on
// the faces with outgoing radiance (1 + ρ), and the expected light the clamp removes at a receiver
// x is (1 + ρ) (ρ/π) I(x), with
//   I(x) = ∫_{d < c} cos θ_x cos θ_y (1/d² − 1/c²) dA(y)
// over the faces perpendicular to x's whose plane lies within c (coplanar points have cos θ = 0;
// inside a cube every pair sees each other). Around the foot of x on such a face, at height h,
// y = foot + r (cos φ, sin φ), and cos θ_x cos θ_y / d² dA = A(φ) r² h / d⁴ dr dφ with A(φ)
// the cosine of φ's direction against x's normal. The substitution r = h tan s makes the radial
// integral elementary:
//   ∫_0^{r_m} A r² h / d⁴ (1 − d²/c²) dr = A [s/2 − sin(2s)/4 − (h²/c²)(tan s − s)],
// s = atan(r_m / h), r_m the distance along φ to the disc's rim √(c² − h²) or the face's edge.
constexpr double kPiD = 3.14159265358979323846;
// Only the angle is integrated numerically (midpoint rule, fine enough that its error is far
// below the compensation's noise).
double FurnaceClampIntegral(Vec3 x, double c) {
  const double p[3] = {x.x, x.y, x.z};
  // x's own face: the coordinate at 0 or 1; its normal points into the cube.
  int k0 = 0;
  double best = 1e9;
  for (int k = 0; k < 3; ++k)
    for (double side : {0.0, 1.0})
      if (std::abs(p[k] - side) < best) best = std::abs(p[k] - side), k0 = k;
  const double nx_sign = p[k0] < 0.5 ? 1.0 : -1.0;
  double total = 0;
  for (int k = 0; k < 3; ++k) {
    if (k == k0) continue;
    for (double side : {0.0, 1.0}) {
      const double h = std::abs(p[k] - side);
      if (h >= c) continue;
      const double rim = std::sqrt(c * c - h * h);
      // The face's in-plane axes: k0 (x's normal's axis) and the third one.
      const int k2 = 3 - k - k0;
      constexpr int kAngles = 4096;
      double sum = 0;
      for (int i = 0; i < kAngles; ++i) {
        const double phi = (i + 0.5) * 2 * kPiD / kAngles;
        const double u = std::cos(phi), v = std::sin(phi);  // along k0, along k2
        const double a = u * nx_sign;                       // cos against x's normal
        if (a <= 0) continue;
        double rm = rim;
        rm = std::min(rm, u > 0 ? (1 - p[k0]) / u : -p[k0] / u);
        if (v != 0) rm = std::min(rm, v > 0 ? (1 - p[k2]) / v : -p[k2] / v);
        const double s = std::atan2(rm, h);
        sum += a * (s / 2 - std::sin(2 * s) / 4 - h * rm / (c * c) + h * h * s / (c * c));
      }
      total += sum * 2 * kPiD / kAngles;
    }
  }
  return total;
}

// What the compensation adds is the clamp's expected loss, against the closed form on the
// render's own receivers: at the default clamp (0.01, a 0.2% loss) within 0.02% of the light,
// and at 0.2, where the clamp takes 4%, within the same. The VPLs' own loss (the stats'
// energy_lost_fraction) cannot show this: its variance is unbounded (docs/rendering.md, "What
// the compensation leaves"). scripts/report-clamp.sh reads the recorded properties.
TEST(ClampCompensation, WhatItAddsIsTheFurnacesExpectedLossInClosedForm) {
  TempDir dir;
  const double rho = 0.5;
  const std::string path = dir.Write("box.pbrt", FurnaceBox(float(rho), 2));
  for (const double clamp : {0.01, 0.2}) {
    RenderSettings s;
    s.method = "brute";
    s.width = s.height = 64;
    s.spp = 4;
    s.lights = 500;
    s.seed = 5;
    s.params = {"clamp=" + std::to_string(clamp), "clamp_compensation=64"};
    PhaseTimes times;
    const Plan plan = BuildPlan(path, s, &times);
    const GatherOutcome outcome = RunStagesLocally(plan, nullptr, &times);
    const double c = plan.matrix->clamp_distance();
    // Each camera hit's unclamped light is (1 + ρ) ρ (the cube covers its hemisphere), times its
    // throughput (its share of the pixel where coverage paths group at the cube's edges).
    double lost = 0, unclamped = 0;
    for (const ShadingPoint& sp : plan.receivers->points) {
      const double share = double(sp.throughput.g);
      lost += share * (1 + rho) * rho / kPiD * FurnaceClampIntegral(sp.p, c);
      unclamped += share * (1 + rho) * rho;
    }
    const double compensated = outcome.counters.clamp_compensated / unclamped;
    const double exact = lost / unclamped;
    RecordProperty("clamp_" + std::to_string(clamp) + "_expected_loss", std::to_string(exact));
    RecordProperty("clamp_" + std::to_string(clamp) + "_compensated", std::to_string(compensated));
    EXPECT_GT(exact, clamp < 0.1 ? 0.001 : 0.03) << clamp;  // the clamp does take light
    EXPECT_NEAR(compensated, exact, 0.0002) << clamp;
    // The probe (clamp_probe.h) measures the same expectation from more light sets: at 0.2 the
    // pairs closer than c are many and its standard error is small.
    if (clamp > 0.1) {
      const ClampLossProbe probe =
          ProbeClampLoss(*plan.scene, *plan.receivers, plan.light_options, plan.matrix_options, 128);
      EXPECT_GT(probe.pairs, 100000u);
      EXPECT_LT(probe.stderr_, 0.02 * probe.mean) << probe.mean / unclamped << " vs " << exact;
      EXPECT_NEAR(probe.mean / unclamped, exact, 4 * probe.stderr_ / unclamped);
    }
  }
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

// In media the compensation is on by default only where every light is distant or an
// environment (L_s is bounded there; beside a point or area light its samples' variance is
// not): a slab of fog under a distant light gets it, the same slab with a point light added does
// not unless asked for, and asking changes the image only by what the media samples add.
TEST(ClampCompensation, InMediaByDefaultOnlyWhereNoLightIsFinite) {
  TempDir dir;
  const std::string slab =
      "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\nIntegrator \"volpath\" \"integer maxdepth\" [3]\n"
      "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\nWorldBegin\n"
      "LightSource \"distant\" \"rgb L\" [3 3 3] \"point3 from\" [0.3 0.2 1] \"point3 to\" [0 0 0]\n"
      "MakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.1 0.1 0.1] \"rgb sigma_s\" [2 2 2]\n"
      "AttributeBegin\nMediumInterface \"m\" \"\"\nMaterial \"interface\"\n"
      "Shape \"trianglemesh\" \"point3 P\" [-4 -4 1.5  4 -4 1.5  4 4 1.5  -4 4 1.5] \"integer indices\" [0 1 2 0 2 3]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-4 -4 1  4 -4 1  4 4 1  -4 4 1] \"integer indices\" [0 2 1 0 3 2]\nAttributeEnd\n"
      "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0] \"integer indices\" [0 1 2 0 2 3]\n";
  const std::string lamp = "LightSource \"point\" \"rgb I\" [1 1 1] \"point3 from\" [0 0 3]\n";
  auto render = [&](const std::string& name, const std::string& text, std::vector<std::string> params) {
    RenderSettings s;
    s.method = "brute";
    s.lights = 200;
    s.seed = 4;
    s.params = std::move(params);
    return RenderScene(dir.Write(name, text), s);
  };
  const RenderOutput distant = render("distant.pbrt", slab, {});
  EXPECT_EQ(distant.stats["clamp"]["media_compensation"], true);
  EXPECT_GT(distant.stats["clamp"]["compensation_paths"].get<double>(), 0);
  EXPECT_GT(distant.stats["clamp"]["compensated_fraction"].get<double>(), 0);
  const RenderOutput off = render("distant.pbrt", slab, {"media_compensation=0"});
  EXPECT_EQ(off.stats["clamp"]["media_compensation"], false);
  EXPECT_EQ(off.stats["clamp"]["compensation_paths"], 0);  // the floor sees nothing within c
  EXPECT_GT(Mean(distant.image), Mean(off.image));

  const RenderOutput lamp_default = render("lamp.pbrt", slab + lamp, {});
  EXPECT_EQ(lamp_default.stats["clamp"]["media_compensation"], false);
  const RenderOutput lamp_on = render("lamp.pbrt", slab + lamp, {"media_compensation=1"});
  EXPECT_EQ(lamp_on.stats["clamp"]["media_compensation"], true);
  EXPECT_GT(lamp_on.stats["clamp"]["compensation_paths"].get<double>(), 0);
}

}  // namespace test_clamp_compensation
}  // namespace lightfarm
