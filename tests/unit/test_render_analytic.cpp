// Whole-pipeline tests against closed-form answers: a scene file in, an image out.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <vector>
#include <tbb/global_control.h>

#include <cmath>
#include <string>

#include "common/render/render_job.h"
#include "common/receivers/receivers.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_render_analytic {

using testing::TempDir;

// Orthographic camera looking down -z at the square [-1,1]² of the plane z = 0.
std::string PlaneScene(const std::string& lights, int res, int maxdepth = 1) {
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(res) +
         "] \"integer yresolution\" [" + std::to_string(res) +
         "]\nPixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [" +
         std::to_string(maxdepth) +
         "]\nLookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
         "WorldBegin\n" +
         lights +
         "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n"
         "  \"integer indices\" [0 1 2 0 2 3]\n";
}

RenderOutput Render(const TempDir& dir, const std::string& text, RenderSettings s) {
  return RenderScene(dir.Write("scene.pbrt", text), s);
}

// L = ρ/π · I · cos θ / d² for a Lambertian plane under a point light at height h on the axis.
TEST(AnalyticRender, LambertianPlaneUnderPointLight) {
  TempDir dir;
  const int res = 32;
  const float h = 1.f;
  RenderSettings s;
  s.spp = 256;
  s.lights = 1;
  RenderOutput out = Render(
      dir, PlaneScene("LightSource \"point\" \"rgb I\" [3.14159265 3.14159265 3.14159265]"
                      " \"point3 from\" [0 0 1]\n", res),
      s);
  ASSERT_EQ(out.image.width, res);
  double max_rel = 0;
  for (int py = 0; py < res; ++py)
    for (int px = 0; px < res; ++px) {
      // The box-filtered pixel is the mean of L over its area (integrated here on a 16² grid).
      // The setup is symmetric about the axis, so the image orientation does not matter.
      double expected = 0;
      for (int sy = 0; sy < 16; ++sy)
        for (int sx = 0; sx < 16; ++sx) {
          double x = -1 + (px + (sx + 0.5) / 16) * 2.0 / res;
          double y = -1 + (py + (sy + 0.5) / 16) * 2.0 / res;
          double d2 = x * x + y * y + double(h) * double(h);
          expected += 0.5 / M_PI * M_PI * (double(h) / std::sqrt(d2)) / d2 / 256;
        }
      RGB v = out.image.at(px, py);
      max_rel = std::max(max_rel, std::abs(double(v.g) - expected) / expected);
      EXPECT_FLOAT_EQ(v.r, v.g);
    }
  // 256 stratified samples estimate that mean; L varies by up to ~8% across a pixel, and the
  // (0,2)-sequence's error for such a smooth integrand is well below 0.1%.
  EXPECT_LT(max_rel, 1e-3);
  EXPECT_EQ(out.stats["lights"]["point"], 1);
  EXPECT_EQ(out.stats["lights"]["vpl"], 0);  // maxdepth 1: no indirect VPLs
}

// Splitting a light into four of a quarter the power leaves the image unchanged.
TEST(AnalyticRender, SplittingALightIntoFourQuartersGivesTheSameImage) {
  TempDir dir;
  RenderSettings s;
  s.spp = 4;
  s.lights = 4;
  std::string one = "LightSource \"point\" \"rgb I\" [2 1 0.5] \"point3 from\" [0.3 -0.2 0.8]\n";
  std::string four;
  for (int i = 0; i < 4; ++i)
    four += "LightSource \"point\" \"rgb I\" [0.5 0.25 0.125] \"point3 from\" [0.3 -0.2 0.8]\n";
  Image a = Render(dir, PlaneScene(one, 24), s).image;
  Image b = Render(dir, PlaneScene(four, 24), s).image;
  ASSERT_TRUE(a.SameSize(b));
  for (size_t i = 0; i < a.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(a.pixels[i][c], b.pixels[i][c], 1e-6f * std::max(1.f, a.pixels[i][c]));
}

// Inside a closed sphere that emits Le and reflects with albedo ρ, a path with k scattering
// events carries Le·ρ^k, so L = Le·Σ_{k≤D} ρ^k → Le/(1−ρ). On a sphere the form factor between
// any two points is constant (cos θ₁ cos θ₂ / d² = 1/(4R²)), so the VPL estimate has no
// singularity: the test isolates the light transport, not the clamp.
std::string FurnaceScene(int maxdepth) {
  return "Film \"rgb\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n"
         "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [" +
         std::to_string(maxdepth) +
         "]\nLookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" [60]\n"
         "WorldBegin\nAttributeBegin\n  ReverseOrientation\n"
         "  AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
         "  Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
         "  Shape \"sphere\" \"float radius\" [1]\nAttributeEnd\n";
}

double MeanGreen(const Image& img) {
  double sum = 0;
  for (const RGB& c : img.pixels) sum += double(c.g);
  return sum / double(img.pixels.size());
}

TEST(AnalyticRender, ClosedFurnaceConvergesToLeOverOneMinusAlbedo) {
  TempDir dir;
  const double rho = 0.5;
  double previous_error = 1e9;
  for (int depth : {1, 2, 4, 12}) {
    RenderSettings s;
    s.spp = 1;
    s.lights = 20000;
    s.seed = 7;
    RenderOutput out = Render(dir, FurnaceScene(depth), s);
    double expected = (1 - std::pow(rho, depth + 1)) / (1 - rho);
    double mean = MeanGreen(out.image);
    // Direct light is exact here; indirect VPLs carry Monte Carlo noise of the particle paths.
    EXPECT_NEAR(mean, expected, 0.01 * expected) << "maxdepth " << depth;
    double error_to_limit = std::abs(mean - 1 / (1 - rho));
    EXPECT_LT(error_to_limit, previous_error) << "maxdepth " << depth;
    previous_error = error_to_limit;
  }
  EXPECT_LT(previous_error, 0.01 * 2.0);
}

// Direct lighting alone is exact for any light count: every VPL on the sphere contributes
// ρ/π · (Le·A/N) · 1/(4R²).
TEST(AnalyticRender, FurnaceDirectLightingIsExactForAnyLightCount) {
  TempDir dir;
  for (size_t n : {size_t(1), size_t(7), size_t(500)}) {
    RenderSettings s;
    s.lights = n;
    RenderOutput out = Render(dir, FurnaceScene(1), s);
    for (const RGB& c : out.image.pixels) ASSERT_NEAR(c.g, 1.5f, 1e-3f) << n << " lights";
  }
}

// A smooth coat over a black base is a dielectric mirror: the camera sees the emitter behind it
// scaled by the Fresnel reflectance, through the receivers' unbiased split between the coat's
// delta lobe and the base.
TEST(AnalyticRender, SmoothCoatMirrorsAnEmitterWithFresnelWeight) {
  TempDir dir;
  std::string scene =
      "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
      "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [2]\n"
      "LookAt 0 1 1  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-0.05 0.05 -0.05 0.05]\n"
      "WorldBegin\n"
      "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n"
      "  Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
      "  Shape \"trianglemesh\" \"point3 P\" [-50 -50 -5  50 -50 -5  50 50 -5  -50 50 -5]\n"
      "    \"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n"
      "Material \"coateddiffuse\" \"rgb reflectance\" [0 0 0] \"float roughness\" [0]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-1 0 -1  1 0 -1  1 0 1  -1 0 1] \"integer indices\" [0 1 2 0 2 3]\n";
  RenderSettings s;
  s.spp = 64;
  s.lights = 16;
  RenderOutput out = Render(dir, scene, s);
  // Fresnel reflectance of a dielectric with eta 1.5 at 45 degrees.
  const double c = std::sqrt(0.5), eta = 1.5, sin_t = std::sqrt(0.5) / eta;
  const double cos_t = std::sqrt(1 - sin_t * sin_t);
  const double rs = (c - eta * cos_t) / (c + eta * cos_t), rp = (eta * c - cos_t) / (eta * c + cos_t);
  const double fresnel = 0.5 * (rs * rs + rp * rp);
  EXPECT_NEAR(MeanGreen(out.image), fresnel, 0.01 * fresnel);
}

// Camera-side supersampling (ReceiverOptions::camera_paths): an emitting rhombus
// |x|/0.8 + |y|/0.6 ≤ 1 over a black floor, seen by an orthographic camera through a box
// filter, so each pixel's exact value is L × the share of the pixel the rhombus covers. One
// sample per pixel makes the edge pixels 0 or L; the pilot marks them and their camera paths
// bring them to their coverage, while the flat pixels (inside, outside) get no extra path.
std::string RhombusScene(int res) {
  return "Film \"rgb\" \"integer xresolution\" [" + std::to_string(res) + "] \"integer yresolution\" [" +
         std::to_string(res) +
         "]\nPixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
         "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
         "WorldBegin\n"
         "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [2 2 2] \"bool twosided\" true\n"
         "  Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
         "  Shape \"trianglemesh\" \"point3 P\" [0.8 0 0.5  0 0.6 0.5  -0.8 0 0.5  0 -0.6 0.5]\n"
         "    \"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n"
         "Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0] \"integer indices\" [0 1 2 0 2 3]\n";
}

// Area of the square [x0,x1]×[y0,y1] inside the rhombus: the square clipped by its four
// half-planes (Sutherland–Hodgman), then the shoelace formula. Symmetric in x and y, so the
// image's orientation does not matter.
double RhombusCoverage(double x0, double y0, double x1, double y1) {
  std::vector<std::array<double, 2>> poly = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  for (double sx : {-1.0, 1.0})
    for (double sy : {-1.0, 1.0}) {
      auto inside = [&](const std::array<double, 2>& p) { return sx * p[0] / 0.8 + sy * p[1] / 0.6 <= 1; };
      std::vector<std::array<double, 2>> out;
      for (size_t i = 0; i < poly.size(); ++i) {
        const auto& a = poly[i];
        const auto& b = poly[(i + 1) % poly.size()];
        if (inside(a)) out.push_back(a);
        if (inside(a) != inside(b)) {
          const double fa = sx * a[0] / 0.8 + sy * a[1] / 0.6 - 1, fb = sx * b[0] / 0.8 + sy * b[1] / 0.6 - 1;
          const double t = fa / (fa - fb);
          out.push_back({a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])});
        }
      }
      poly = std::move(out);
    }
  double area = 0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const auto& a = poly[i];
    const auto& b = poly[(i + 1) % poly.size()];
    area += a[0] * b[1] - b[0] * a[1];
  }
  return std::abs(area) / 2 / ((x1 - x0) * (y1 - y0));
}

struct CoverageError {
  double max_abs = 0;  // largest |pixel − L·coverage|, in units of L
  double mean = 0;     // image mean, in units of L
};

CoverageError RhombusError(const Image& img, int res) {
  CoverageError e;
  for (int py = 0; py < res; ++py)
    for (int px = 0; px < res; ++px) {
      const double x0 = -1 + 2.0 * px / res, y0 = -1 + 2.0 * py / res;
      const double expected = RhombusCoverage(x0, y0, x0 + 2.0 / res, y0 + 2.0 / res);
      const double v = double(img.at(px, py).g) / 2;
      e.max_abs = std::max(e.max_abs, std::abs(v - expected));
      e.mean += v / double(res * res);
    }
  return e;
}

TEST(CameraSideSupersampling, ALightsEdgePixelsConvergeToTheirCoverage) {
  TempDir dir;
  const int res = 24;
  const std::string path = dir.Write("rhombus.pbrt", RhombusScene(res));
  RenderSettings s;
  s.method = "brute";
  s.lights = 50;
  s.seed = 3;
  // One path per receiver sample: coverage paths (docs/rendering.md, "Coverage") would average the
  // edges' emission by themselves.
  s.params = {"camera_paths=2048", "coverage=1"};
  RenderOutput on = RenderScene(path, s);
  const CoverageError e_on = RhombusError(on.image, res);
  // 2049 stratified samples of a pixel cut by a straight edge: far below 1% of L.
  EXPECT_LT(e_on.max_abs, 0.01);
  // The rhombus covers 0.96 of the screen's area 4.
  EXPECT_NEAR(e_on.mean, 0.24, 0.24 * 1e-3);
  // Only the pixels near an edge got camera paths: the edge pixels and their neighbours.
  const uint64_t active = on.stats["receivers"]["camera_active_pixels"];
  EXPECT_GT(active, size_t(4 * res / 2));
  EXPECT_LT(active, size_t(res * res / 2));
  // They share 2048 paths each (rounded per pixel).
  const double shared = on.stats["receivers"]["camera_paths"].get<double>();
  EXPECT_NEAR(shared, double(active) * 2048, double(active));
  EXPECT_EQ(on.stats["receivers"]["camera_pilot_paths"], size_t(res * res * kCameraPilotPaths));

  // Off, the edge pixels are 0 or L: the option is what brought them to their coverage.
  s.params = {"camera_paths=0", "coverage=1"};
  RenderOutput off = RenderScene(path, s);
  const CoverageError e_off = RhombusError(off.image, res);
  EXPECT_GT(e_off.max_abs, 0.3);
  EXPECT_EQ(off.stats["receivers"]["camera_paths"], 0);
  EXPECT_EQ(off.stats["receivers"]["camera_pilot_paths"], 0);
  // Same receivers either way: the gathered part (black here) and the image inside the rhombus.
  EXPECT_EQ(on.image.at(res / 2, res / 2), off.image.at(res / 2, res / 2));
}

// The active pixels share their paths by the pilot's spread (ShareActivePaths): the rhombus's two
// halves emit 200 and 2, so the bright half's edge pixels vary 100× more and get most of the
// paths. Measured in units of each half's L, its edges are then closer to their coverage than the
// dim half's; an even share would make the two alike (same geometry, same path counts).
TEST(CameraSideSupersampling, PathsGoWhereThePilotSawTheLightVaryMost) {
  TempDir dir;
  const int res = 24;
  const std::string scene =
      "Film \"rgb\" \"integer xresolution\" [24] \"integer yresolution\" [24]\n"
      "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
      "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
      "WorldBegin\n"
      "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [200 200 200] \"bool twosided\" true\n"
      "  Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
      "  Shape \"trianglemesh\" \"point3 P\" [0.8 0 0.5  0 0.6 0.5  -0.8 0 0.5] \"integer indices\" [0 1 2]\n"
      "AttributeEnd\n"
      "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [2 2 2] \"bool twosided\" true\n"
      "  Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
      "  Shape \"trianglemesh\" \"point3 P\" [0.8 0 0.5  -0.8 0 0.5  0 -0.6 0.5] \"integer indices\" [0 1 2]\n"
      "AttributeEnd\n";
  RenderSettings s;
  s.method = "brute";
  s.lights = 50;
  s.params = {"camera_paths=256", "coverage=1"};
  const std::string path = dir.Write("halves.pbrt", scene);
  double bright_sq = 0, dim_sq = 0;
  size_t bright_n = 0, dim_n = 0;
  for (const uint64_t seed : {1, 2}) {
    s.seed = seed;
    const RenderOutput out = RenderScene(path, s);
    // Which image rows hold the bright half (y > 0): the image's orientation is the camera's.
    const bool bright_on_top = out.image.at(res / 2, res / 4).g > out.image.at(res / 2, 3 * res / 4).g;
    for (int py = 0; py < res; ++py)
      for (int px = 0; px < res; ++px) {
        // Whole pixels on one side of y = 0, not touching it (the seam between the halves).
        const int row = bright_on_top ? res - 1 - py : py;  // row 0 at y = -1
        const double x0 = -1 + 2.0 * px / res, y0 = -1 + 2.0 * row / res;
        if (y0 < 2.0 / res && y0 + 2.0 / res > -2.0 / res) continue;
        const double coverage = RhombusCoverage(x0, y0, x0 + 2.0 / res, y0 + 2.0 / res);
        if (coverage <= 0 || coverage >= 1) continue;  // not on the rhombus's edge
        const bool bright = y0 > 0;
        const double L = bright ? 200 : 2;
        const double err = double(out.image.at(px, py).g) / L - coverage;
        (bright ? bright_sq : dim_sq) += err * err;
        ++(bright ? bright_n : dim_n);
      }
  }
  ASSERT_GT(bright_n, 20u);
  ASSERT_GT(dim_n, 20u);
  const double bright_rms = std::sqrt(bright_sq / double(bright_n)), dim_rms = std::sqrt(dim_sq / double(dim_n));
  // Paths ∝ spread: the bright edges get ~7× the dim edges' paths here, √7 ≈ 2.6× less error.
  EXPECT_LT(bright_rms, 0.6 * dim_rms) << "bright " << bright_rms << " dim " << dim_rms;
  EXPECT_GT(dim_rms, 0.0);
}

// A light far smaller than a pixel: a 0.02 × 0.02 square inside one pixel of 24² over [-1, 1]²
// covers 5.8% of it, so the pilot's 4 paths there miss it four times in five. Its projected
// bounds activate the pixel instead, and the camera paths find its energy: the image's sum is
// L × its area over a pixel's area, within the noise of 2049 samples (~117 hits, 9%).
constexpr double kSpeckPixel = 2.0 / 24, kSpeckSide = 0.02;

// `lens`: extra parameters of the orthographic camera (a thin lens).
std::string SpeckScene(const std::string& lens) {
  // The centre of pixel (12, 12) is at (pixel / 2, pixel / 2) in either orientation of the image.
  const double c = kSpeckPixel / 2, h = kSpeckSide / 2;
  auto v = [&](double x, double y) { return std::to_string(x) + " " + std::to_string(y) + " 0.5  "; };
  return "Film \"rgb\" \"integer xresolution\" [24] \"integer yresolution\" [24]\n"
         "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [1]\n"
         "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1] " + lens + "\n"
         "WorldBegin\nAttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [1000 1000 1000] \"bool twosided\" true\n"
         "  Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
         "  Shape \"trianglemesh\" \"point3 P\" [" + v(c - h, c - h) + v(c + h, c - h) + v(c + h, c + h) + v(c - h, c + h) +
         "]\n    \"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n";
}

struct SpeckRender {
  double sum = 0;  // green over the image
  size_t lit = 0;  // pixels with any light
  uint64_t active = 0;
  uint64_t camera_paths = 0;
};

SpeckRender RenderSpeck(const std::string& path, uint64_t seed) {
  RenderSettings s;
  s.method = "brute";
  s.lights = 10;
  s.seed = seed;
  s.params = {"camera_paths=2048"};
  const RenderOutput out = RenderScene(path, s);
  SpeckRender r;
  for (const RGB& p : out.image.pixels) {
    r.sum += double(p.g);
    r.lit += p.g > 0;
  }
  r.active = out.stats["receivers"]["camera_active_pixels"];
  r.camera_paths = out.stats["receivers"]["camera_paths"];
  return r;
}

TEST(CameraSideSupersampling, ALightSmallerThanAPixelIsFoundByItsProjection) {
  TempDir dir;
  const double expected = 1000 * kSpeckSide * kSpeckSide / (kSpeckPixel * kSpeckPixel);  // 57.6
  const std::string path = dir.Write("speck.pbrt", SpeckScene(""));
  // Eight seeds: the pilot alone would leave the pixel inactive in most of them.
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    const SpeckRender r = RenderSpeck(path, seed);
    EXPECT_NEAR(r.sum, expected, 0.3 * expected) << "seed " << seed;
    EXPECT_EQ(r.lit, 1u) << "seed " << seed;  // the light lies inside one pixel
    // Its bounds and the pixels around them, 3×3, are active; nothing else is.
    EXPECT_EQ(r.active, 9u) << "seed " << seed;
  }
  // Through a thin lens: in focus (the light 4.5 from the camera) its image is still a point;
  // focused at 2.5 it is a disk of radius 0.25 · (4.5/2.5 - 1) = 0.2, 2.4 pixels, each of whose
  // pixels sees the light in ~0.3% of its paths. The active pixels cover it (its 6×6 bounds
  // and one pixel around, at least) and the camera paths find its energy, the same.
  for (const auto& [lens, min_active] : {std::pair{"\"float lensradius\" [0.25] \"float focaldistance\" [4.5]", 9u},
                                         std::pair{"\"float lensradius\" [0.25] \"float focaldistance\" [2.5]", 36u}}) {
    const SpeckRender r = RenderSpeck(dir.Write("speck-lens.pbrt", SpeckScene(lens)), 1);
    EXPECT_NEAR(r.sum, expected, 0.3 * expected) << lens;
    EXPECT_GE(r.active, uint64_t(min_active)) << lens;
  }
}

// The same light seen only in a smooth glass plane (L S E): the orthographic camera looks down
// on the plane z = -y, which reflects its rays into +y, onto a 0.02 square at y = 3 whose mirror
// image lies inside pixel (12, 12). A path there finds it with the pixel's share 5.8% times the
// Fresnel reflectance at 45°, one in ~340; the 4-path pilot never sees it, and 2049 paths would
// hit it ~6 times. The delta-chain probe marks the image and gives its 3×3 pixels enough paths
// for ~40 hits each, so over four seeds the image holds L·R·A/A_pixel within 25% (~160 hits).
std::string GlassSpeckScene() {
  const double c = kSpeckPixel / 2, h = kSpeckSide / 2;
  // Screen (x, y) reflects onto (x, 3, -y).
  auto v = [&](double x, double y) { return std::to_string(x) + " 3 " + std::to_string(-y) + "  "; };
  return "Film \"rgb\" \"integer xresolution\" [24] \"integer yresolution\" [24]\n"
         "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [3]\n"
         "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
         "WorldBegin\nAttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [1000 1000 1000] \"bool twosided\" true\n"
         "  Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
         "  Shape \"trianglemesh\" \"point3 P\" [" + v(c - h, c - h) + v(c + h, c - h) + v(c + h, c + h) + v(c - h, c + h) +
         "]\n    \"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n"
         "Material \"dielectric\" \"float eta\" [1.5]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 4  4 -4 4  4 4 -4  -4 4 -4] \"integer indices\" [0 1 2 0 2 3]\n";
}

TEST(CameraSideSupersampling, ASmallLightsReflectionInGlassIsFoundByTheDeltaProbe) {
  TempDir dir;
  const double c = std::sqrt(0.5), eta = 1.5, sin_t = std::sqrt(0.5) / eta;
  const double cos_t = std::sqrt(1 - sin_t * sin_t);
  const double rs = (c - eta * cos_t) / (c + eta * cos_t), rp = (eta * c - cos_t) / (eta * c + cos_t);
  const double fresnel = 0.5 * (rs * rs + rp * rp);
  const double expected = 1000 * fresnel * kSpeckSide * kSpeckSide / (kSpeckPixel * kSpeckPixel);
  const std::string path = dir.Write("glass-speck.pbrt", GlassSpeckScene());
  double sum = 0;
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    const SpeckRender r = RenderSpeck(path, seed);
    sum += r.sum / 4;
    // The image and the pixels around it, and nothing else; each with more than camera_paths.
    EXPECT_EQ(r.active, 9u) << "seed " << seed;
    EXPECT_GT(r.camera_paths, 9u * 4 * 2048) << "seed " << seed;
  }
  EXPECT_NEAR(sum, expected, 0.25 * expected);
}

// Simulate only what the scene calls for: a camera that can see no emitter (a point light over
// a diffuse plane) gets no pilot and no camera paths, and the image is the same bits as with
// the option off.
TEST(CameraSideSupersampling, NothingToSeeNoCameraPaths) {
  TempDir dir;
  const std::string path =
      dir.Write("plane.pbrt", PlaneScene("LightSource \"point\" \"rgb I\" [1 1 1] \"point3 from\" [0 0 1]\n", 16, 2));
  RenderSettings s;
  s.lights = 200;
  RenderOutput def = RenderScene(path, s);
  EXPECT_EQ(def.stats["receivers"]["camera_paths"], 0);
  EXPECT_EQ(def.stats["receivers"]["camera_pilot_paths"], 0);
  s.params = {"camera_paths=0", "coverage=1"};
  RenderOutput off = RenderScene(path, s);
  ASSERT_TRUE(def.image.SameSize(off.image));
  for (size_t i = 0; i < def.image.pixels.size(); ++i) ASSERT_EQ(def.image.pixels[i], off.image.pixels[i]);
}

TEST(Determinism, SameSeedSameBitsWithOneOrTwoThreads) {
  RenderSettings s;
  s.width = 24;
  s.height = 24;
  s.spp = 2;
  s.lights = 3000;
  s.seed = 42;
  std::string scene = testing::SharedScene("cornell-box");
  RenderOutput a, b;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    a = RenderScene(scene, s);
  }
  {
    tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    b = RenderScene(scene, s);
  }
  ASSERT_TRUE(a.image.SameSize(b.image));
  for (size_t i = 0; i < a.image.pixels.size(); ++i)
    ASSERT_EQ(a.image.pixels[i], b.image.pixels[i]) << "pixel " << i;
  EXPECT_EQ(a.stats["rays"]["shadow"], b.stats["rays"]["shadow"]);
  // A different seed changes the light set, and so the image.
  s.seed = 43;
  RenderOutput c = RenderScene(scene, s);
  size_t differing = 0;
  for (size_t i = 0; i < a.image.pixels.size(); ++i) differing += !(a.image.pixels[i] == c.image.pixels[i]);
  EXPECT_GT(differing, a.image.pixels.size() / 2);
}

// The media scene builds and renders (media errors with file:line: test_media.cpp).
TEST(RenderErrors, MediaSceneRendersFinite) {
  RenderSettings s;
  s.width = s.height = 8;
  s.lights = 10;
  RenderOutput out = RenderScene(testing::SharedScene("volumetric-caustic"), s);
  EXPECT_EQ(out.stats["film"]["nan_samples"], 0);
  for (const RGB& p : out.image.pixels) ASSERT_TRUE(p.IsFinite());
  const auto& effects = out.stats["effects"];
  EXPECT_NE(std::find(effects.begin(), effects.end(), "media"), effects.end());
}

TEST(RenderErrors, UnknownMethodAndParamAreOptionErrors) {
  TempDir dir;
  std::string path = dir.Write("s.pbrt", PlaneScene("LightSource \"point\"\n", 4));
  RenderSettings s;
  s.method = "no-such-method";
  EXPECT_THROW(RenderScene(path, s), OptionError);
  s.method = "brute";
  s.params = {"clampp=0.1"};
  EXPECT_THROW(RenderScene(path, s), OptionError);
  s.params = {"clamp=-1"};
  EXPECT_THROW(RenderScene(path, s), OptionError);
}

}  // namespace test_render_analytic
}  // namespace lightfarm

namespace lightfarm {
namespace test_render_analytic {

// The matrix refers to the plan's receivers and lights; moving a plan must keep it valid.
TEST(Plan, MovedPlanRendersTheSameImage) {
  RenderSettings s;
  s.width = s.height = 12;
  s.lights = 300;
  std::string scene = testing::SharedScene("cornell-box");
  Plan original = BuildPlan(scene, s, nullptr);
  GatherOutcome a = RunStagesLocally(original, nullptr, nullptr);
  Plan moved(std::move(original));
  Plan assigned;
  assigned = std::move(moved);
  GatherOutcome b = RunStagesLocally(assigned, nullptr, nullptr);
  ASSERT_EQ(a.row_sums.size(), b.row_sums.size());
  for (size_t i = 0; i < a.row_sums.size(); ++i) {
    ASSERT_EQ(a.row_sums[i].r, b.row_sums[i].r) << i;
    ASSERT_EQ(a.row_sums[i].g, b.row_sums[i].g) << i;
  }
}

}  // namespace test_render_analytic
}  // namespace lightfarm
