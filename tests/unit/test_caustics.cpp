// Caustics seen directly (common/lights/caustic_photons.h, common/matrix/caustic_gather.cpp):
// light through a glass sphere onto a diffuse floor (L S+ D E) and into fog (L S+ M E) has no
// connection a virtual light can make; the photons gathered on the rows bring it back, close to
// what the path tracer finds, only where a scene has such paths, and with the same bits for any
// thread count.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cstdio>
#include <string>

#include "common/render/render_job.h"
#include "tests/common/caustic_scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_caustics {

using testing::SphereOverFloor;
using testing::TempDir;

RenderOutput Render(const std::string& path, const std::string& method, int spp, std::vector<std::string> params = {},
                    size_t lights = 3000) {
  RenderSettings s;
  s.method = method;
  s.spp = spp;
  s.lights = lights;
  s.seed = 5;
  s.params = std::move(params);
  return RenderScene(path, s);
}

double Lum(const RGB& c) { return double(c.Luminance()); }

// Mean luminance of `img` over the pixels of `mask`.
double MaskedMean(const Image& img, const std::vector<uint8_t>& mask) {
  double s = 0;
  size_t n = 0;
  for (size_t i = 0; i < img.pixels.size(); ++i)
    if (mask[i]) s += Lum(img.pixels[i]), ++n;
  return n ? s / double(n) : 0;
}

// The caustic's pixels: where the path tracer sees clearly more light than the virtual lights
// alone carry.
std::vector<uint8_t> CausticMask(const Image& truth, const Image& without) {
  std::vector<uint8_t> mask(truth.pixels.size(), 0);
  for (size_t i = 0; i < mask.size(); ++i) mask[i] = Lum(truth.pixels[i]) > 1.5 * Lum(without.pixels[i]) + 0.02;
  return mask;
}

size_t Count(const std::vector<uint8_t>& mask) {
  size_t n = 0;
  for (uint8_t m : mask) n += m;
  return n;
}

// The path tracer's image and brute force's with and without photons, measured over the
// caustic's pixels (where the path tracer sees clearly more than the virtual lights alone) and
// over the whole image.
struct CausticComparison {
  size_t pixels = 0;
  double truth = 0, with = 0, without = 0;              // means over the caustic
  double all_truth = 0, all_with = 0, all_without = 0;  // means over the image
  double photons_used = 0, energy_fraction = 0;
};

CausticComparison CompareCaustic(const std::string& path, int spp, size_t lights) {
  const RenderOutput truth = Render(path, "path", 1024);
  const RenderOutput without = Render(path, "brute", spp, {"caustic_photons=0"}, lights);
  const RenderOutput with = Render(path, "brute", spp, {}, lights);
  const std::vector<uint8_t> mask = CausticMask(truth.image, without.image), all(mask.size(), 1);
  CausticComparison c;
  c.pixels = Count(mask);
  c.truth = MaskedMean(truth.image, mask);
  c.with = MaskedMean(with.image, mask);
  c.without = MaskedMean(without.image, mask);
  c.all_truth = MaskedMean(truth.image, all);
  c.all_with = MaskedMean(with.image, all);
  c.all_without = MaskedMean(without.image, all);
  c.photons_used = with.stats["caustics"]["photons_used"].get<double>();
  c.energy_fraction = with.stats["caustics"]["energy_fraction"].get<double>();
  std::printf("%s: caustic (%zu px): path %.4f, brute with photons %.4f, without %.4f\n", path.c_str(), c.pixels,
              c.truth, c.with, c.without);
  return c;
}

TEST(Caustics, GlassSphereCausticOnTheFloorMatchesThePathTracer) {
  TempDir dir;
  const CausticComparison c = CompareCaustic(dir.Write("caustic.pbrt", SphereOverFloor(true, false)), 4, 3000);
  ASSERT_GT(c.pixels, 20u) << "the scene must show a caustic";
  // Without photons the caustic is missing; with them it is there, within the photon map's blur
  // and both renders' noise.
  EXPECT_LT(c.without, 0.5 * c.truth);
  EXPECT_NEAR(c.with, c.truth, 0.12 * c.truth);
  // And the whole image agrees: nothing counted twice.
  EXPECT_NEAR(c.all_with, c.all_truth, 0.05 * c.truth);
  EXPECT_GT(c.photons_used, 0);
  EXPECT_GT(c.energy_fraction, 0.01);
}

TEST(Caustics, BeamThroughFogMatchesThePathTracer) {
  TempDir dir;
  // Few lights keep brute force over eye segments affordable; their own bias (a few percent
  // here) cancels in the caustic's increment, which is what is compared.
  const CausticComparison c = CompareCaustic(dir.Write("beam.pbrt", SphereOverFloor(true, true)), 2, 1000);
  ASSERT_GT(c.pixels, 20u) << "the scene must show a caustic";
  EXPECT_LT(c.without, 0.6 * c.truth);
  EXPECT_NEAR(c.with - c.without, c.truth - c.without, 0.15 * (c.truth - c.without));
  EXPECT_NEAR(c.all_with - c.all_without, c.all_truth - c.all_without, 0.05 * c.truth);
  EXPECT_GT(c.photons_used, 0);
}

TEST(Caustics, OnlyWhereTheSceneHasThem) {
  TempDir dir;
  // A diffuse sphere: no delta lobe anywhere, so no photon is traced or gathered.
  const RenderOutput diffuse = Render(dir.Write("diffuse.pbrt", SphereOverFloor(false, false)), "brute", 1);
  EXPECT_EQ(diffuse.stats["caustics"]["photons"], 0);
  EXPECT_EQ(diffuse.stats["caustics"]["photons_used"], 0);
  EXPECT_EQ(diffuse.stats["caustics"]["energy_fraction"], 0.0);
  // The path tracer finds caustics by itself.
  const std::string glass = dir.Write("glass.pbrt", SphereOverFloor(true, false));
  EXPECT_EQ(Render(glass, "path", 1).stats["caustics"]["photons"], 0);
  EXPECT_GT(Render(glass, "lightcuts", 1).stats["caustics"]["photons_used"].get<double>(), 0);
}

TEST(Caustics, SameBitsForAnyThreadCountAndEveryMethodSeesThem) {
  TempDir dir;
  const std::string path = dir.Write("beam.pbrt", SphereOverFloor(true, true));
  RenderOutput one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = Render(path, "brute", 1, {"caustic_photons=20000"}, 200);
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = Render(path, "brute", 1, {"caustic_photons=20000"}, 200);
  }
  EXPECT_TRUE(testing::SameBits(one.image, two.image));
  EXPECT_GT(one.stats["caustics"]["photons_used"].get<double>(), 0);
  // The photons are part of the light transport, not of a method: another method gathers the
  // same ones on the same rows.
  const RenderOutput ac = Render(path, "adaptive-completion", 1, {"caustic_photons=20000"}, 200);
  EXPECT_EQ(ac.stats["caustics"]["photons_used"], one.stats["caustics"]["photons_used"]);
}

}  // namespace test_caustics
}  // namespace lightfarm
