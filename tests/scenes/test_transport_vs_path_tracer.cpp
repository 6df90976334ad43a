// lightfarm's many-light transport against an independent volumetric path tracer
// (tests/oracle/volpath/path_tracer.h: pbrt-v4 volpath depth counting, next-event estimation, delta
// tracking; it shares only the parser, the Embree scene, the BSDFs and the camera). A fog-filled
// box seen through an interface wall, lit by a small area light on its ceiling (just out of view:
// one camera sample that hits it would outweigh a region), brute force with
// VRLs (the default) and with medium VPLs must match the path tracer's region means at maxdepth 1
// (direct light on the walls and single scattering in the fog) and 3 (two more bounces through
// walls and fog). A wrong σ_s, phase normalisation, VRL power or one bounce too many or too few
// moves a region by far more than the tolerance (maxdepth 1 → 3 changes them by 70–190%).
// Measured on the red channel (seeds 3 and 4): maxdepth 1 within 0.9% of the path tracer
// (4096 spp) in every region, maxdepth 3 within 2.7%, VRLs and medium VPLs alike.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "tests/oracle/volpath/path_tracer.h"
#include "common/render/render_job.h"
#include "common/scene/scene_description.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_transport_vs_path_tracer {

using namespace lightfarm::testing;

std::string FogBox(int max_depth) {
  return "Integrator \"volpath\" \"integer maxdepth\" [" + std::to_string(max_depth) + "]\n" +
         R"(LookAt 0 1 4.2  0 1 0  0 1 0
Camera "perspective" "float fov" [24]
Film "rgb" "integer xresolution" [16] "integer yresolution" [16]
WorldBegin
MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [0.15 0.2 0.3]
  "rgb sigma_s" [0.6 0.6 0.6] "float g" [0.3]
Material "diffuse" "rgb reflectance" [0.6 0.6 0.6]
Shape "trianglemesh" "point3 P" [-1 0 -1  1 0 -1  1 0 1  -1 0 1] "integer indices" [0 2 1 0 3 2]
Shape "trianglemesh" "point3 P" [-1 2 -1  -1 2 1  1 2 1  1 2 -1] "integer indices" [0 2 1 0 3 2]
Shape "trianglemesh" "point3 P" [-1 0 -1  -1 2 -1  1 2 -1  1 0 -1] "integer indices" [0 2 1 0 3 2]
Material "diffuse" "rgb reflectance" [0.7 0.2 0.2]
Shape "trianglemesh" "point3 P" [-1 0 -1  -1 0 1  -1 2 1  -1 2 -1] "integer indices" [0 2 1 0 3 2]
Material "diffuse" "rgb reflectance" [0.2 0.7 0.2]
Shape "trianglemesh" "point3 P" [1 0 -1  1 2 -1  1 2 1  1 0 1] "integer indices" [0 2 1 0 3 2]
AttributeBegin
  MediumInterface "fog" ""
  Material "interface"
  Shape "trianglemesh" "point3 P" [-1 0 1  1 0 1  1 2 1  -1 2 1] "integer indices" [0 1 2 0 2 3]
AttributeEnd
AttributeBegin
  MediumInterface "" "fog"
  AreaLightSource "diffuse" "rgb L" [12 12 12]
  Material "diffuse" "rgb reflectance" [0 0 0]
  Shape "trianglemesh" "point3 P" [-0.25 1.98 -0.25  0.25 1.98 -0.25  0.25 1.98 0.25  -0.25 1.98 0.25]
    "integer indices" [0 1 2 0 2 3]
AttributeEnd
)";
}

struct RegionMean {
  double value = 0, standard_error = 0;
};

// Luminance mean over the pixels [x0, x0+w) × [y0, y0+h), with the standard error of that mean
// when per-pixel variances of the mean are given.
RegionMean Mean(const Image& img, const Image* variance, int x0, int y0, int w, int h) {
  RegionMean m;
  double var = 0;
  for (int y = y0; y < y0 + h; ++y)
    for (int x = x0; x < x0 + w; ++x) {
      m.value += double(img.at(x, y).Luminance());
      if (variance) {
        // Luminance is linear: its variance from the channels' (independent enough for a bound)
        const RGB v = variance->at(x, y);
        var += 0.2126 * 0.2126 * double(v.r) + 0.7152 * 0.7152 * double(v.g) +
               0.0722 * 0.0722 * double(v.b);
      }
    }
  const double n = double(w) * double(h);
  m.value /= n;
  m.standard_error = std::sqrt(var) / n;
  return m;
}

// The independent tracer's image of a fog box (box filter, 4096 spp, seed 3) with its variance.
PathTracedImage TraceWithChecker(const std::string& path) {
  SceneBuildOptions build;
  build.filter = "box";
  std::unique_ptr<Scene> scene = Scene::Build(ParseSceneFile(path), build);
  VolpathCheckOptions pt;
  pt.spp = 4096;
  pt.seed = 3;
  return RenderPathTraced(*scene, pt);
}

// Brute force on a fog box: box filter, 4 spp, seed 3, `lights` lights.
RenderOutput RenderBrute(const std::string& path, size_t lights, std::vector<std::string> params) {
  RenderSettings s;
  s.method = "brute";
  s.filter = "box";
  s.lights = lights;
  s.spp = 4;
  s.seed = 3;
  s.params = std::move(params);
  return RenderScene(path, s);
}

// The whole image and its halves: top (back wall, ceiling, fog near the light), bottom
// (floor), left and right (the coloured walls), as {x0, y0, w, h}.
constexpr int kRegions[5][4] = {{0, 0, 16, 16}, {0, 0, 16, 8}, {0, 8, 16, 8}, {0, 0, 8, 16}, {8, 0, 8, 16}};

void ExpectMatchesPathTracer(int max_depth, const std::string& media_lights, double tolerance) {
  TempDir dir;
  const std::string path = dir.Write("fog-box.pbrt", FogBox(max_depth));
  const PathTracedImage traced = TraceWithChecker(path);
  const RenderOutput lf = RenderBrute(path, 6000, {"media_lights=" + media_lights, "segments_per_ray=6"});
  ASSERT_GT(lf.stats["receivers"]["segments"].get<double>(), 0);

  for (const auto& r : kRegions) {
    const RegionMean a = Mean(traced.mean, &traced.variance_of_mean, r[0], r[1], r[2], r[3]);
    const RegionMean b = Mean(lf.image, nullptr, r[0], r[1], r[2], r[3]);
    ASSERT_GT(a.value, 0);
    // The path tracer's own noise (4 standard errors) plus the many-light estimate's tolerance
    const double allowed = tolerance * a.value + 4 * a.standard_error;
    EXPECT_NEAR(b.value, a.value, allowed)
        << "maxdepth " << max_depth << ", " << media_lights << ", region " << r[0] << "," << r[1]
        << " " << r[2] << "x" << r[3] << ": path tracer " << a.value << " ± " << a.standard_error
        << ", lightfarm " << b.value;
  }
}

TEST(TransportVsPathTracer, DirectLightAndSingleScatteringMatch) {
  ExpectMatchesPathTracer(1, "vrl", 0.03);
}

TEST(TransportVsPathTracer, MultipleScatteringWithVirtualRayLightsMatches) {
  ExpectMatchesPathTracer(3, "vrl", 0.05);
}

TEST(TransportVsPathTracer, MultipleScatteringWithMediumVplsMatches) {
  ExpectMatchesPathTracer(3, "vpl", 0.05);
}

// The clamp's compensation in the fog (clamp_compensation.cpp): at clamp 0.2 (c ≈ 0.35, a
// fifth of the box) the clamp takes about a tenth of the image from brute force, mostly from the
// fog's eye segments and from walls that see the fog; the compensation (eye segments and
// surface rows alike, their first vertex forced within c) gives it back region by region.
TEST(TransportVsPathTracer, TheClampsLossInTheFogIsCompensated) {
  TempDir dir;
  const std::string path = dir.Write("fog-box.pbrt", FogBox(3));
  const PathTracedImage traced = TraceWithChecker(path);
  const RenderOutput clamped = RenderBrute(path, 2000, {"clamp=0.2", "clamp_compensation=0"});
  const RenderOutput compensated =
      RenderBrute(path, 2000, {"clamp=0.2", "clamp_compensation=16", "media_compensation=1"});
  EXPECT_GT(compensated.stats["clamp"]["compensation_paths"].get<double>(), 0);
  for (const auto& r : kRegions) {
    const RegionMean a = Mean(traced.mean, &traced.variance_of_mean, r[0], r[1], r[2], r[3]);
    const RegionMean lost = Mean(clamped.image, nullptr, r[0], r[1], r[2], r[3]);
    const RegionMean back = Mean(compensated.image, nullptr, r[0], r[1], r[2], r[3]);
    const std::string where = "region " + std::to_string(r[0]) + "," + std::to_string(r[1]) + " " +
                              std::to_string(r[2]) + "x" + std::to_string(r[3]) + ": path tracer " +
                              std::to_string(a.value) + " ± " + std::to_string(a.standard_error);
    EXPECT_LT(lost.value, 0.95 * a.value - 4 * a.standard_error) << where << ", clamped " << lost.value;
    EXPECT_NEAR(back.value, a.value, 0.03 * a.value + 4 * a.standard_error) << where << ", compensated " << back.value;
  }
}

// The `path` method (MIS, delta and ratio tracking, chromatic σ_a) against the independent
// tracer (next-event estimation only, closed-form transmittance): same regions, and every
// channel of the whole image, within both estimates' noise (4 standard errors each) plus 1%.
void ExpectPathMethodMatchesPathTracer(int max_depth) {
  TempDir dir;
  const std::string path = dir.Write("fog-box.pbrt", FogBox(max_depth));
  const PathTracedImage traced = TraceWithChecker(path);

  RenderSettings s;
  s.method = "path";
  s.filter = "box";
  s.spp = 4096;
  s.seed = 4;
  const RenderOutput lf = RenderScene(path, s);
  for (const auto& r : kRegions) {
    const RegionMean a = Mean(traced.mean, &traced.variance_of_mean, r[0], r[1], r[2], r[3]);
    const RegionMean b = Mean(lf.image, nullptr, r[0], r[1], r[2], r[3]);
    ASSERT_GT(a.value, 0);
    EXPECT_NEAR(b.value, a.value, 0.01 * a.value + 8 * a.standard_error)
        << "maxdepth " << max_depth << ", region " << r[0] << "," << r[1] << " " << r[2] << "x" << r[3]
        << ": independent tracer " << a.value << " ± " << a.standard_error << ", path " << b.value;
  }
  for (int c = 0; c < 3; ++c) {
    double a = 0, b = 0;
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) {
        a += double(traced.mean.at(x, y)[c]);
        b += double(lf.image.at(x, y)[c]);
      }
    EXPECT_NEAR(b, a, 0.02 * a) << "maxdepth " << max_depth << ", channel " << c;
  }
}

TEST(TransportVsPathTracer, PathMethodMatchesTheIndependentTracerDirectAndSingleScattering) {
  ExpectPathMethodMatchesPathTracer(1);
}

TEST(TransportVsPathTracer, PathMethodMatchesTheIndependentTracerMultipleScattering) {
  ExpectPathMethodMatchesPathTracer(4);
}

}  // namespace test_transport_vs_path_tracer
}  // namespace lightfarm
