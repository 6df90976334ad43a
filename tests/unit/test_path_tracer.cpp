// The `path` method (common/integrator/path_tracer.h) against closed forms: a furnace, whose
// radiance is a geometric series in the albedo, cut exactly where pbrt-v4's depth rule cuts it;
// a Lambertian plane under a spherical and under a point light. Each estimator alone (BSDF
// sampling, light sampling) and their MIS combination must converge to the same answer, which is
// what makes the MIS weights right. Determinism across threads and tilings is checked too.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <vector>
#include <string>

#include "common/render/render_job.h"
#include "common/lights/emitters.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_path_tracer {

using testing::TempDir;

// A camera inside a closed, two-sided emitting sphere of reflectance rho and radiance Le: every
// camera ray sees Le + rho·Le + rho²·Le + ... up to maxdepth scattering vertices.
std::string Furnace(int maxdepth, float rho) {
  return "Film \"rgb\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n"
         "Sampler \"sobol\" \"integer pixelsamples\" [64]\n"
         "Integrator \"volpath\" \"integer maxdepth\" [" + std::to_string(maxdepth) + "]\n"
         "LookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" [90]\nWorldBegin\n"
         "AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n"
         "Material \"diffuse\" \"rgb reflectance\" [" + std::to_string(rho) + " " + std::to_string(rho) +
         " " + std::to_string(rho) + "]\n"
         "Shape \"sphere\" \"float radius\" [1]\n";
}

double MeanGreen(const Image& img) {
  double sum = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) sum += double(img.at(x, y).g);
  return sum / (double(img.width) * img.height);
}

RenderOutput RenderPath(const TempDir& dir, const std::string& text, const std::string& strategy, int spp = 0) {
  RenderSettings s;
  s.method = "path";
  s.spp = spp;
  s.seed = 5;
  s.params = {"strategy=" + strategy};
  return RenderScene(dir.Write("scene.pbrt", text), s);
}

// maxdepth 3 keeps exactly Le (1 + ρ + ρ² + ρ³): emission found after the last vertex counts,
// a fourth bounce does not. ρ = 0.5: 1.875; unlimited depth: Le / (1 − ρ) = 2.
TEST(PathTracer, FurnaceIsTheGeometricSeriesCutAtMaxDepth) {
  TempDir dir;
  for (const std::string strategy : {"mis", "bsdf", "light"}) {
    const RenderOutput cut = RenderPath(dir, Furnace(3, 0.5f), strategy);
    EXPECT_NEAR(MeanGreen(cut.image), 1.875, 0.01) << strategy;
    const RenderOutput full = RenderPath(dir, Furnace(200, 0.5f), strategy);
    EXPECT_NEAR(MeanGreen(full.image), 2.0, 0.012) << strategy;
    EXPECT_EQ(full.stats["spp"], 64);  // the scene's pixelsamples
    EXPECT_GT(full.stats["method_stats"]["path.roulette"].get<double>(), 0);
  }
  // maxdepth 0: only the emission the camera sees.
  const RenderOutput none = RenderPath(dir, Furnace(0, 0.5f), "mis");
  EXPECT_NEAR(MeanGreen(none.image), 1.0, 1e-6);
}

// Orthographic camera looking down at the Lambertian plane z = 0 (ρ = 0.5) over [-1, 1]².
std::string PlaneUnder(const std::string& light) {
  return "Film \"rgb\" \"integer xresolution\" [32] \"integer yresolution\" [32]\nPixelFilter \"box\"\n"
         "Integrator \"path\" \"integer maxdepth\" [1]\n"
         "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
         "WorldBegin\n" + light +
         "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0] \"integer indices\" [0 1 2 0 2 3]\n";
}

// The pixel's box-filtered mean of radiance(x, y) over its area, on a 16² grid.
template <typename Fn>
double PixelMean(int px, int py, int res, Fn radiance) {
  double sum = 0;
  for (int sy = 0; sy < 16; ++sy)
    for (int sx = 0; sx < 16; ++sx)
      sum += radiance(-1 + (px + (sx + 0.5) / 16) * 2.0 / res, 1 - (py + (sy + 0.5) / 16) * 2.0 / res);
  return sum / 256;
}

// A sphere of radiance L and radius r fully above the horizon irradiates E = π L (r/d)² cos θ,
// so the plane reflects ρ L r² cos θ / d². The sphere (seen by the centre pixels) is excluded.
TEST(PathTracer, PlaneUnderASphereLightConvergesWithEveryStrategy) {
  TempDir dir;
  const double h = 1, r = 0.25;
  const std::string light =
      "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [2 2 2]\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
      "Translate 0 0 1\nShape \"sphere\" \"float radius\" [0.25]\nAttributeEnd\n";
  double expected = 0;
  int counted = 0;
  std::vector<double> truth(32 * 32, -1);
  for (int py = 0; py < 32; ++py)
    for (int px = 0; px < 32; ++px) {
      const double cx = -1 + (px + 0.5) / 16, cy = 1 - (py + 0.5) / 16;
      if (cx * cx + cy * cy < 0.4 * 0.4) continue;  // the sphere and its silhouette
      truth[size_t(py * 32 + px)] = PixelMean(px, py, 32, [&](double x, double y) {
        const double d2 = x * x + y * y + h * h;
        return 0.5 * 2.0 * r * r * (h / std::sqrt(d2)) / d2;
      });
      expected += truth[size_t(py * 32 + px)];
      ++counted;
    }
  expected /= counted;
  for (const std::string strategy : {"mis", "light", "bsdf"}) {
    const RenderOutput out = RenderPath(dir, PlaneUnder(light), strategy, 1024);
    double got = 0;
    for (int py = 0; py < 32; ++py)
      for (int px = 0; px < 32; ++px) {
        const double t = truth[size_t(py * 32 + px)];
        if (t < 0) continue;
        got += double(out.image.at(px, py).g);
      }
    got /= counted;
    // Over the ~900 pixels × 1024 samples: BSDF sampling alone finds the small sphere rarely
    // (a ~6% chance per sample), within 2%; the light-sampled estimators within 1% (~3σ).
    EXPECT_NEAR(got, expected, (strategy == "bsdf" ? 0.02 : 0.01) * expected) << strategy;
  }
}

// A square emitter parallel to the plane: Lambert's polygon formula gives the irradiance exactly,
// E = L/2 · |Σ_i Θ_i n·(u_i × u_{i+1})/|u_i × u_{i+1}||, Θ_i the angle between consecutive
// corners seen from the point; the plane reflects ρ/π · E.
TEST(PathTracer, PlaneUnderAQuadLightConvergesWithEveryStrategy) {
  TempDir dir;
  const std::string light =
      "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [3 3 3] \"bool twosided\" true\n"
      "Material \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-0.3 -0.3 1  0.3 -0.3 1  0.3 0.3 1  -0.3 0.3 1] \"integer indices\" [0 1 2 0 2 3]\n"
      "AttributeEnd\n";
  auto radiance = [](double x, double y) {
    const double corners[4][2] = {{-0.3, -0.3}, {0.3, -0.3}, {0.3, 0.3}, {-0.3, 0.3}};
    double sum = 0;
    for (int i = 0; i < 4; ++i) {
      const double* a = corners[i];
      const double* b = corners[(i + 1) % 4];
      double u[3] = {a[0] - x, a[1] - y, 1}, v[3] = {b[0] - x, b[1] - y, 1};
      const double lu = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
      const double lv = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      const double cz = u[0] * v[1] - u[1] * v[0];  // n = +z: only the cross product's z matters
      const double cx = u[1] * v[2] - u[2] * v[1], cy = u[2] * v[0] - u[0] * v[2];
      const double theta = std::acos(std::clamp((u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (lu * lv), -1.0, 1.0));
      sum += theta * cz / std::sqrt(cx * cx + cy * cy + cz * cz);
    }
    return 0.5 / M_PI * (3.0 / 2.0 * std::abs(sum));
  };
  double expected = 0;
  int counted = 0;
  std::vector<double> truth(32 * 32, -1);
  for (int py = 0; py < 32; ++py)
    for (int px = 0; px < 32; ++px) {
      const double cx = -1 + (px + 0.5) / 16, cy = 1 - (py + 0.5) / 16;
      if (std::abs(cx) < 0.36 && std::abs(cy) < 0.36) continue;  // the camera sees the emitter there
      truth[size_t(py * 32 + px)] = PixelMean(px, py, 32, radiance);
      expected += truth[size_t(py * 32 + px)];
      ++counted;
    }
  expected /= counted;
  for (const std::string strategy : {"mis", "light", "bsdf"}) {
    const RenderOutput out = RenderPath(dir, PlaneUnder(light), strategy, 512);
    double got = 0;
    for (size_t i = 0; i < truth.size(); ++i)
      if (truth[i] >= 0) got += double(out.image.pixels[i].g);
    got /= counted;
    EXPECT_NEAR(got, expected, (strategy == "bsdf" ? 0.02 : 0.01) * expected) << strategy;
  }
}

// A point light is reached by light sampling only: ρ/π · I cos θ / d², as the matrix methods'
// analytic test, and per pixel (the only noise is the pixel's area).
TEST(PathTracer, PlaneUnderAPointLightIsExactPerPixel) {
  TempDir dir;
  const RenderOutput out = RenderPath(
      dir, PlaneUnder("LightSource \"point\" \"rgb I\" [3.14159265 3.14159265 3.14159265] \"point3 from\" [0 0 1]\n"),
      "mis", 256);
  double max_rel = 0;
  for (int py = 0; py < 32; ++py)
    for (int px = 0; px < 32; ++px) {
      const double t = PixelMean(px, py, 32, [](double x, double y) {
        const double d2 = x * x + y * y + 1;
        return 0.5 / std::sqrt(d2) / d2;
      });
      max_rel = std::max(max_rel, std::abs(double(out.image.at(px, py).g) - t) / t);
    }
  EXPECT_LT(max_rel, 1e-3);
  EXPECT_EQ(out.stats["rays"]["camera"], 32 * 32 * 256);
  EXPECT_EQ(out.stats["rays"]["shadow"], 32 * 32 * 256);  // one per vertex, every path has one
}

// The sampler's density at a point it produced is the density PdfArea reports for a path that
// hits that point: otherwise the MIS weights would not sum to one.
TEST(PathTracer, EmitterSampleDensityMatchesHitDensity) {
  TempDir dir;
  const std::string light =
      "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [2 2 2]\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n"
      "Translate 0.3 -0.2 1\nShape \"sphere\" \"float radius\" [0.25]\nAttributeEnd\n"
      "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 3 1]\n"
      "Shape \"trianglemesh\" \"point3 P\" [-1 -1 2  1 -1 2  1 1 2  -1 1 2] \"integer indices\" [0 2 1 0 3 2]\nAttributeEnd\n";
  std::unique_ptr<Scene> scene =
      Scene::Build(ParseSceneFile(dir.Write("s.pbrt", PlaneUnder(light))), SceneBuildOptions{});
  const EmitterSampler sampler(*scene);
  Rng rng(3);
  int checked = 0;
  for (int i = 0; i < 2000; ++i) {
    const Vec3 p{rng.Uniform() - 0.5f, rng.Uniform() - 0.5f, 0.01f};
    const auto ls = sampler.Sample(p, rng.Uniform(), {rng.Uniform(), rng.Uniform()});
    if (!ls) continue;
    SurfaceHit hit;
    if (!scene->Intersect({p, ls->wi, kInfinity}, &hit)) continue;
    if (Length(hit.p - ls->p_light) > 1e-3f) continue;  // the sampled point is hidden (back of the sphere)
    // At grazing incidence dist²/cos is ill-conditioned in the normal: the geometric normal Embree
    // reports and the sampled point's differ by ~1e-5 rad, which moves the density 0.2% at cos 0.005.
    if (std::abs(Dot(hit.ng, ls->wi)) < 0.02f) continue;
    const int emitter = scene->shapes()[hit.shape].area_emitter;
    ASSERT_GE(emitter, 0);
    EXPECT_NEAR(sampler.PdfArea(uint32_t(emitter), p, hit), ls->pdf, 2e-3f * ls->pdf);
    ++checked;
  }
  EXPECT_GT(checked, 800);
}

// The same bits for one thread or two, and whichever tasks the samples fall in when the passes
// are the same.
TEST(PathTracer, DeterministicAcrossThreadCounts) {
  TempDir dir;
  const std::string path = dir.Write("scene.pbrt", Furnace(6, 0.6f));
  RenderSettings s;
  s.method = "path";
  s.spp = 24;
  s.seed = 9;
  s.params = {"tile=5", "pass_spp=7"};
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
  EXPECT_EQ(one.stats["tasks"], 16 * 4);  // 4×4 tiles of 5 pixels (16 = 5+5+5+1), 4 passes (7+7+7+3)
  EXPECT_EQ(one.stats["rays"]["shadow"], two.stats["rays"]["shadow"]);
}

TEST(PathTracer, RejectsUnknownStrategyAndMatrixOnlyParameters) {
  TempDir dir;
  const std::string path = dir.Write("scene.pbrt", Furnace(2, 0.5f));
  RenderSettings s;
  s.method = "path";
  s.params = {"strategy=photon"};
  EXPECT_THROW(RenderScene(path, s), OptionError);
  s.method = "brute";
  s.params = {"pass_spp=4"};  // a film method's tiling: not a brute-force parameter
  EXPECT_THROW(RenderScene(path, s), OptionError);
}

}  // namespace test_path_tracer
}  // namespace lightfarm
