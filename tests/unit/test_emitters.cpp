// Each emitter kind as a column of the matrix, against closed-form radiance on a Lambertian
// plane (ρ = 0.5) seen by an orthographic camera.
#include <gtest/gtest.h>

#include <cmath>

#include "common/render/render_job.h"
#include "common/image/image_io.h"
#include "common/util/sampling.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_emitters {

using testing::TempDir;

std::string Plane(const std::string& lights, int maxdepth = 1) {
  return "Film \"rgb\" \"integer xresolution\" [16] \"integer yresolution\" [16]\n"
         "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [" +
         std::to_string(maxdepth) +
         "]\nLookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
         "WorldBegin\n" + lights +
         "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n"
         "  \"integer indices\" [0 1 2 0 2 3]\n";
}

RenderOutput Render(const TempDir& dir, const std::string& text, size_t lights, int spp = 1) {
  RenderSettings s;
  s.lights = lights;
  s.spp = spp;
  return RenderScene(dir.Write("scene.pbrt", text), s);
}

double Mean(const Image& img, int c) {
  double sum = 0;
  for (const RGB& p : img.pixels) sum += double(p[c]);
  return sum / double(img.pixels.size());
}

// Distant light of radiance L along the normal: Lo = ρ/π · L (pbrt-v4's "L" is the irradiance
// scale of a delta direction).
TEST(Emitters, DistantLightOnPlane) {
  TempDir dir;
  RenderOutput out = Render(dir, Plane("LightSource \"distant\" \"rgb L\" [3.14159265 6.2831853 0]"
                                       " \"point3 from\" [0 0 1] \"point3 to\" [0 0 0]\n"), 1);
  for (const RGB& p : out.image.pixels) {
    ASSERT_NEAR(p.r, 0.5f, 1e-5f);
    ASSERT_NEAR(p.g, 1.0f, 1e-5f);
    ASSERT_EQ(p.b, 0.f);
  }
  EXPECT_EQ(out.stats["lights"]["directional"], 1);
}

// A spot light pointing down: inside the inner cone it equals the point light; outside the outer
// cone it is black.
TEST(Emitters, SpotLightConeAndFalloff) {
  TempDir dir;
  // Height 1, cone 20° (delta 5°): inner radius tan 15° = 0.268, outer tan 20° = 0.364.
  RenderOutput out = Render(dir, Plane("LightSource \"spot\" \"rgb I\" [3.14159265 3.14159265 3.14159265]"
                                       " \"point3 from\" [0 0 1] \"point3 to\" [0 0 0]"
                                       " \"float coneangle\" [20] \"float conedelta\" [5]\n"), 1, 16);
  int inside = 0, outside = 0;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      // Pixel extents in world units (the setup is symmetric, orientation does not matter).
      double x0 = -1 + x * 0.125, y0 = -1 + y * 0.125;
      double rmin = std::hypot(std::max({0.0, x0, -(x0 + 0.125)}), std::max({0.0, y0, -(y0 + 0.125)}));
      double rmax = std::hypot(std::max(std::abs(x0), std::abs(x0 + 0.125)),
                               std::max(std::abs(y0), std::abs(y0 + 0.125)));
      float v = out.image.at(x, y).g;
      if (rmax < std::tan(15 * M_PI / 180)) {
        // Point-light value averaged over the pixel is within [L(rmax), L(rmin)].
        auto L = [](double r) { return 0.5 / std::pow(1 + r * r, 1.5); };
        EXPECT_GE(v, L(rmax) * 0.999);
        EXPECT_LE(v, L(rmin) * 1.001);
        ++inside;
      } else if (rmin > std::tan(20 * M_PI / 180)) {
        EXPECT_EQ(v, 0.f);
        ++outside;
      }
    }
  EXPECT_GE(inside, 4);  // the 2x2 pixels around the axis lie fully inside the inner cone
  EXPECT_GT(outside, 100);
}

// Under a uniform environment of radiance L an unoccluded upward Lambertian plane reflects ρ·L.
TEST(Emitters, UniformInfiniteLightBecomesDirectionalLights) {
  TempDir dir;
  RenderOutput out = Render(dir, Plane("LightSource \"infinite\" \"rgb L\" [1 2 4]\n"), 4096);
  EXPECT_NEAR(Mean(out.image, 0), 0.5, 0.01);
  EXPECT_NEAR(Mean(out.image, 1), 1.0, 0.02);
  EXPECT_NEAR(Mean(out.image, 2), 2.0, 0.04);
  EXPECT_EQ(out.stats["lights"]["directional"], 4096);
  auto effects = out.stats["effects"].get<std::vector<std::string>>();
  EXPECT_NE(std::find(effects.begin(), effects.end(), "environment"), effects.end());
}

// An equal-area octahedral image (pbrt-v4's format) read through OpenImageIO: bright in the upper
// hemisphere (the map's inner diamond), dim below. The plane sees only the upper one.
TEST(Emitters, ImageInfiniteLightIsImportanceSampled) {
  TempDir dir;
  const int n = 64;
  Image env(n, n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      Vec3 d = EqualAreaSquareToSphere({(x + 0.5f) / n, (y + 0.5f) / n});
      env.at(x, y) = d.z > 0 ? RGB(2.f) : RGB(0.25f);
    }
  WriteEXR(dir.Path("env.exr"), env);
  RenderOutput out = Render(dir, Plane("LightSource \"infinite\" \"string filename\" \"env.exr\"\n"), 8192);
  // ρ·L_top = 1; pixels straddling the horizon contribute at grazing angles only.
  EXPECT_NEAR(Mean(out.image, 1), 1.0, 0.02);
  // Importance sampling puts most directional lights in the bright half: 8 of every 9 by power.
  EXPECT_EQ(out.stats["lights"]["directional"], 8192);
}

TEST(Emitters, NonSquareEnvironmentImageIsAnError) {
  TempDir dir;
  WriteEXR(dir.Path("wide.exr"), Image(8, 4, RGB(1.f)));
  EXPECT_THROW(Render(dir, Plane("LightSource \"infinite\" \"string filename\" \"wide.exr\"\n"), 16),
               SceneError);
}

TEST(Sampling, EqualAreaMappingRoundTrips) {
  for (int i = 0; i < 1000; ++i) {
    Vec2 p{(i % 37 + 0.5f) / 37, (i / 37 % 29 + 0.5f) / 29};
    Vec3 d = EqualAreaSquareToSphere(p);
    ASSERT_NEAR(Length(d), 1.f, 1e-5f);
    Vec2 q = EqualAreaSphereToSquare(d);
    ASSERT_NEAR(p.x, q.x, 1e-4f);
    ASSERT_NEAR(p.y, q.y, 1e-4f);
  }
}

}  // namespace test_emitters
}  // namespace lightfarm
