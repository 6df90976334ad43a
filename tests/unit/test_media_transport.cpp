// Media in the existing transport: camera paths and shadow connections through interface
// surfaces (generalized visibility = visibility × transmittance), and the zero counts on
// surface-only scenes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "common/render/render_job.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_media_transport {

using testing::TempDir;

// A Lambertian plane (ρ = 0.5) at z = 0 under a distant light along -z (Lo = ρ/π · L = 0.5 for
// L = π), seen by an orthographic camera from z = 5. `slab` goes between them.
std::string PlaneScene(const std::string& slab, int maxdepth = 1) {
  return "Film \"rgb\" \"integer xresolution\" [8] \"integer yresolution\" [8]\n"
         "PixelFilter \"box\"\nIntegrator \"path\" \"integer maxdepth\" [" +
         std::to_string(maxdepth) +
         "]\nLookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\" \"float screenwindow\" [-1 1 -1 1]\n"
         "WorldBegin\n"
         "LightSource \"distant\" \"rgb L\" [3.14159265 3.14159265 3.14159265]"
         " \"point3 from\" [0 0 1] \"point3 to\" [0 0 0]\n" +
         slab +
         "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 0  4 -4 0  4 4 0  -4 4 0]\n"
         "  \"integer indices\" [0 1 2 0 2 3]\n";
}

// An absorbing slab z ∈ [1, 1.5] bounded by two interface planes whose normals point out of it.
std::string AbsorbingSlab(float sigma_a) {
  return "MakeNamedMedium \"ink\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [" +
         std::to_string(sigma_a) + " " + std::to_string(sigma_a) + " " +
         std::to_string(sigma_a) +
         "] \"rgb sigma_s\" [0 0 0]\n"
         "AttributeBegin\nMediumInterface \"ink\" \"\"\nMaterial \"interface\"\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 1.5  4 -4 1.5  4 4 1.5  -4 4 1.5]\n"
         "  \"integer indices\" [0 1 2 0 2 3]\n"
         "Shape \"trianglemesh\" \"point3 P\" [-4 -4 1  4 -4 1  4 4 1  -4 4 1]\n"
         "  \"integer indices\" [0 2 1 0 3 2]\nAttributeEnd\n";
}

RenderOutput Render(const TempDir& dir, const std::string& text, size_t lights = 1) {
  RenderSettings s;
  s.lights = lights;
  return RenderScene(dir.Write("scene.pbrt", text), s);
}

bool HasEffect(const RenderOutput& out, const std::string& name) {
  const auto& e = out.stats["effects"];
  return std::find(e.begin(), e.end(), name) != e.end();
}

// Camera ray and shadow ray each cross 0.5 of σ_a = 2: the plane's 0.5 becomes 0.5·e^-2.
TEST(MediaTransport, AbsorbingSlabAttenuatesCameraAndShadowRays) {
  TempDir dir;
  RenderOutput out = Render(dir, PlaneScene(AbsorbingSlab(2.f)));
  for (const RGB& p : out.image.pixels) ASSERT_NEAR(p.g, 0.5f * std::exp(-2.f), 1e-4f);
  EXPECT_TRUE(HasEffect(out, "media"));
  EXPECT_GT(out.stats["matrix"]["transmittance_evals"].get<uint64_t>(), 0u);
  EXPECT_GT(out.stats["receivers"]["transmittance_evals"].get<uint64_t>(), 0u);
  // An empty medium (σ = 0) behind the same interfaces changes nothing: interfaces never occlude.
  RenderOutput clear = Render(dir, PlaneScene(AbsorbingSlab(0.f)));
  for (const RGB& p : clear.image.pixels) ASSERT_NEAR(p.g, 0.5f, 1e-5f);
}

// A defined but unused medium is not reachable: no media effect, no transmittance work.
TEST(MediaTransport, SurfaceOnlySceneDoesNoMediaWork) {
  TempDir dir;
  RenderOutput out = Render(dir, PlaneScene(
      "MakeNamedMedium \"unused\" \"string type\" \"homogeneous\"\n"), 1);
  EXPECT_FALSE(HasEffect(out, "media"));
  EXPECT_EQ(out.stats["matrix"]["transmittance_evals"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["receivers"]["transmittance_evals"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["lights"]["vrl"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["receivers"]["segments"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["receivers"]["segment_pieces"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["receivers"]["segment_coverage"].get<uint64_t>(), 1u);
  EXPECT_EQ(out.stats["receivers"]["media_direct_samples"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["lights"]["vrl_flights"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["media"]["tracks"].get<uint64_t>(), 0u);
  EXPECT_EQ(out.stats["media"]["track_knots"].get<uint64_t>(), 0u);
  for (const RGB& p : out.image.pixels) ASSERT_NEAR(p.g, 0.5f, 1e-5f);
}

}  // namespace test_media_transport
}  // namespace lightfarm

namespace lightfarm {
namespace test_media_transport {

// The media scene under brute with medium VPLs (media_lights=vpl; VRLs are the default and
// tested in test_vrl.cpp): eye segments (h + 1 per ray in the gas) and medium VPLs exist,
// each segment row lands in its pixel, and the image stays finite.
TEST(MediaTransport, MediaSceneHasSegmentsAndMediumLights) {
  RenderSettings s;
  s.width = s.height = 6;
  s.lights = 60;
  s.params = {"segments_per_ray=3", "media_lights=vpl"};
  RenderOutput out = RenderScene(testing::SharedScene("volumetric-caustic"), s);
  const auto& st = out.stats;
  EXPECT_GT(st["receivers"]["segments"].get<uint64_t>(), st["receivers"]["camera_samples"].get<uint64_t>());
  EXPECT_LE(st["receivers"]["segments"].get<uint64_t>(), 4 * st["receivers"]["camera_samples"].get<uint64_t>());
  EXPECT_GT(st["lights"]["medium_vpl"].get<uint64_t>(), 0u);
  EXPECT_GT(st["matrix"]["transmittance_evals"].get<uint64_t>(), 0u);
  EXPECT_EQ(st["film"]["nan_samples"], 0);
  double sum = 0;
  for (const RGB& p : out.image.pixels) {
    ASSERT_TRUE(p.IsFinite());
    sum += double(p.Luminance());
  }
  EXPECT_GT(sum, 0.0);
}

}  // namespace test_media_transport
}  // namespace lightfarm
