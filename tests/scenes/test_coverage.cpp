// Coverage paths (docs/rendering.md, "Coverage"): a receiver sample traces K camera paths and
// keeps one receiver per surface they end on, weighted by the surface's share of the sample. On
// a square of one grey in front of a wall of another, lit only directly by a distant light along
// the view axis (so every visible point is lit and each surface shades alike), a pixel inside a
// surface renders as with one path per sample, and an edge pixel as well as K samples per pixel
// render it, at about one receiver per pixel. Where shading varies within a pixel the image's
// mean still equals many samples'.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "common/render/render_job.h"
#include "tests/common/glossy_scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_coverage {

using testing::Lum;
using testing::TempDir;

// The square is tilted about the view axis so that its edges cross pixels at every offset; it
// is centred on the axis, so its shadow (its projection along the axis) hides behind it.
const char* kEdges = R"(
Integrator "path" "integer maxdepth" [ 1 ]
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ] "string filename" [ "edges.exr" ]
PixelFilter "box"
LookAt 0 0 6  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
WorldBegin
LightSource "distant" "point3 from" [ 0 0 6 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
AttributeBegin
  Material "diffuse" "rgb reflectance" [ 0.8 0.8 0.8 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
    "point3 P" [ -10 -10 -1  10 -10 -1  10 10 -1  -10 10 -1 ]
AttributeEnd
AttributeBegin
  Rotate 23 0 0 1
  Material "diffuse" "rgb reflectance" [ 0.3 0.3 0.3 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
    "point3 P" [ -0.7 -0.7 1  0.7 -0.7 1  0.7 0.7 1  -0.7 0.7 1 ]
AttributeEnd
)";

RenderOutput Render(const std::string& path, int spp, int coverage) {
  RenderSettings s;
  s.method = "brute";
  s.spp = spp;
  s.lights = 100;
  s.seed = 5;
  s.params = {"coverage=" + std::to_string(coverage), "camera_paths=0"};
  return RenderScene(path, s);
}

TEST(Coverage, AntialiasesEdgesAtOneReceiverPerSurface) {
  TempDir dir;
  const std::string path = dir.Write("edges.pbrt", kEdges);
  constexpr int K = 16;
  const RenderOutput coverage = Render(path, 1, K);
  const RenderOutput supersampled = Render(path, K, 1);
  const RenderOutput single = Render(path, 1, 1);
  const Image truth = Render(path, 1024, 1).image;
  const Image& a = coverage.image;
  int edge_pixels = 0, inside = 0;
  double err_coverage = 0, err_supersampled = 0, err_single = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      const double t = Lum(truth.at(x, y)), one = Lum(single.image.at(x, y));
      if (std::abs(one - t) > 1e-5 * t) {
        // The truth mixes the single path's surface with another: an edge.
        ++edge_pixels;
        err_coverage += std::abs(Lum(a.at(x, y)) - t);
        err_supersampled += std::abs(Lum(supersampled.image.at(x, y)) - t);
        err_single += std::abs(one - t);
      } else {
        // One surface: the sample's own receiver, as with one path (the shares are exactly 1).
        ++inside;
        EXPECT_NEAR(Lum(a.at(x, y)), one, 1e-6 * one) << x << "," << y;
      }
    }
  std::printf("edge pixels %d: mean error %.4f coverage, %.4f %d samples, %.4f one path\n", edge_pixels,
              err_coverage / edge_pixels, err_supersampled / edge_pixels, K, err_single / edge_pixels);
  EXPECT_GT(edge_pixels, 20);
  EXPECT_GT(inside, 600);
  EXPECT_LT(err_coverage, 0.3 * err_single);
  EXPECT_LT(err_coverage, 1.5 * err_supersampled);
  // About one receiver per pixel: two where the square's edge crosses, against K each.
  const double pixels = double(a.width) * a.height;
  const double points = coverage.stats["receivers"]["points"].get<double>();
  EXPECT_GE(points, pixels);
  EXPECT_LT(points, pixels + 2.0 * edge_pixels);
  EXPECT_EQ(coverage.stats["receivers"]["coverage_paths"].get<double>(), (K - 1) * pixels);
  EXPECT_EQ(supersampled.stats["receivers"]["points"].get<double>(), K * pixels);
}

// The default: one receiver sample of kDefaultCoverage paths per pixel; its image's mean
// equals many samples' where shading varies within a pixel too (a point light near the square).
TEST(Coverage, TheDefaultIsUnbiasedWhereShadingVaries) {
  TempDir dir;
  std::string scene = kEdges;
  const std::string distant = "LightSource \"distant\" \"point3 from\" [ 0 0 6 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 3 3 3 ]";
  scene.replace(scene.find(distant), distant.size(), "LightSource \"point\" \"point3 from\" [ 0.4 0.9 2.2 ] \"rgb I\" [ 4 4 4 ]");
  const std::string path = dir.Write("point.pbrt", scene);
  RenderSettings s;
  s.method = "brute";
  s.lights = 100;
  double sum_cov = 0, sum_ref = 0;
  for (uint64_t seed = 0; seed < 8; ++seed) {
    s.seed = seed;
    s.spp = 1;
    s.params = {};
    const RenderOutput cov = RenderScene(path, s);
    s.spp = 16;
    s.params = {"coverage=1"};
    const RenderOutput ref = RenderScene(path, s);
    for (int y = 0; y < cov.image.height; ++y)
      for (int x = 0; x < cov.image.width; ++x) {
        sum_cov += Lum(cov.image.at(x, y));
        sum_ref += Lum(ref.image.at(x, y));
      }
  }
  EXPECT_NEAR(sum_cov / sum_ref, 1.0, 0.003);
}

}  // namespace test_coverage
}  // namespace lightfarm
