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

#include "common/receivers/receivers.h"
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

// Brute force, 100 lights, seed 5, no camera-side paths, and `params`.
RenderOutput RenderBrute(const std::string& path, int spp, std::vector<std::string> params) {
  RenderSettings s;
  s.method = "brute";
  s.spp = spp;
  s.lights = 100;
  s.seed = 5;
  s.params = std::move(params);
  s.params.push_back("camera_paths=0");
  return RenderScene(path, s);
}

RenderOutput Render(const std::string& path, int spp, int coverage) {
  return RenderBrute(path, spp, {"coverage=" + std::to_string(coverage)});
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

// A shadow's edge inside one surface (ReceiverOptions::coverage_shadows): a wall under a distant
// light, and out of the camera's view a quad whose slanted edge casts a hard shadow across it.
// Every coverage path ends on the wall, so without shadow probes each pixel is one group and
// renders as with one path; with them a pixel across the edge keeps a lit and a shadowed
// receiver, and comes close to many samples per pixel, at about one receiver per pixel.
const char* kShadowEdge = R"(
Integrator "path" "integer maxdepth" [ 1 ]
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ] "string filename" [ "shadow.exr" ]
PixelFilter "box"
LookAt 0 0 6  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
WorldBegin
LightSource "distant" "point3 from" [ 4 0 4 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
Material "diffuse" "rgb reflectance" [ 0.8 0.8 0.8 ]
Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
  "point3 P" [ -10 -10 -1  10 -10 -1  10 10 -1  -10 10 -1 ]
Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
  "point3 P" [ 1.9 -4 3  9 -4 3  9 4 3  3.1 4 3 ]
)";

TEST(Coverage, ShadowProbesAntialiasShadowEdgesOnOneSurface) {
  TempDir dir;
  const std::string path = dir.Write("shadow.pbrt", kShadowEdge);
  const RenderOutput probes = RenderBrute(path, 1, {"coverage=16"});
  const RenderOutput off = RenderBrute(path, 1, {"coverage=16", "coverage_shadows=0"});
  const RenderOutput single = RenderBrute(path, 1, {"coverage=1"});
  const Image truth = RenderBrute(path, 1024, {"coverage=1"}).image;
  int edge_pixels = 0;
  double err_probes = 0, err_off = 0, err_single = 0, sum_probes = 0, sum_truth = 0;
  for (int y = 0; y < truth.height; ++y)
    for (int x = 0; x < truth.width; ++x) {
      const double t = Lum(truth.at(x, y)), one = Lum(single.image.at(x, y));
      sum_probes += Lum(probes.image.at(x, y));
      sum_truth += t;
      if (std::abs(one - t) <= 1e-3 * std::max(t, 1e-3)) continue;
      ++edge_pixels;
      err_probes += std::abs(Lum(probes.image.at(x, y)) - t);
      err_off += std::abs(Lum(off.image.at(x, y)) - t);
      err_single += std::abs(one - t);
    }
  std::printf("shadow-edge pixels %d: mean error %.4f with probes, %.4f without, %.4f one path\n", edge_pixels,
              err_probes / edge_pixels, err_off / edge_pixels, err_single / edge_pixels);
  EXPECT_GT(edge_pixels, 15);
  EXPECT_LT(err_probes, 0.3 * err_single);
  EXPECT_NEAR(err_off, err_single, 1e-6 * err_single);  // one group: the sample's own receiver
  EXPECT_NEAR(sum_probes / sum_truth, 1.0, 0.01);
  const double pixels = double(truth.width) * truth.height;
  EXPECT_EQ(off.stats["receivers"]["points"].get<double>(), pixels);
  const double points = probes.stats["receivers"]["points"].get<double>();
  EXPECT_GT(points, pixels);
  EXPECT_LE(points, pixels + edge_pixels);
}

// A penumbra inside one surface: the same wall and occluder under a small quad light, whose soft
// shadow crosses the view. Across a penumbra a point sees part of the light; one probe at the
// light's centroid parts a pixel only where that point's visibility changes, a probe per quarter
// (coverage_shadows=2, the default) wherever a quarter's does, so its pixels come closer to many
// samples per pixel. The scene is kShadowEdge with its distant light replaced by that quad.
std::string PenumbraScene() {
  std::string scene = kShadowEdge;
  const std::string distant = "LightSource \"distant\" \"point3 from\" [ 4 0 4 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 3 3 3 ]";
  return scene.replace(scene.find(distant), distant.size(), R"(AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 3000 3000 3000 ] "bool twosided" true
  Material "diffuse" "rgb reflectance" [ 0 0 0 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ]
    "point3 P" [ 6.823 -0.25 7.177  7.177 -0.25 6.823  7.177 0.25 6.823  6.823 0.25 7.177 ]
AttributeEnd)");
}

TEST(Coverage, QuarterProbesAntialiasPenumbrae) {
  TempDir dir;
  const std::string path = dir.Write("penumbra.pbrt", PenumbraScene());
  double err_centroid = 0, err_quarters = 0, sum_quarters = 0, sum_truth = 0;
  for (uint64_t seed : {1, 2, 3, 4}) {
    RenderSettings s;
    s.method = "brute";
    s.lights = 64;
    s.seed = seed;
    const auto render = [&](int spp, std::vector<std::string> params) {
      s.spp = spp;
      s.params = std::move(params);
      s.params.push_back("camera_paths=0");
      return RenderScene(path, s).image;
    };
    const Image truth = render(256, {"coverage=1"});
    const Image one = render(1, {"coverage=1"});
    const Image centroid = render(1, {"coverage=16", "coverage_shadows=1"});
    const Image quarters = render(1, {"coverage=16", "coverage_shadows=2"});
    int varying = 0;
    for (int y = 0; y < truth.height; ++y)
      for (int x = 0; x < truth.width; ++x) {
        const double t = Lum(truth.at(x, y)), q = Lum(quarters.at(x, y));
        sum_quarters += q;
        sum_truth += t;
        // Pixels whose one path is off the many-sample mean: where the lighting varies.
        if (std::abs(Lum(one.at(x, y)) - t) <= 1e-3 * std::max(t, 1e-3)) continue;
        ++varying;
        err_centroid += std::abs(Lum(centroid.at(x, y)) - t);
        err_quarters += std::abs(q - t);
      }
    EXPECT_GT(varying, 40) << seed;
  }
  std::printf("penumbra pixels' summed error: %.3f with a probe per quarter, %.3f with one per light\n", err_quarters,
              err_centroid);
  EXPECT_LT(err_quarters, 0.92 * err_centroid);
  EXPECT_NEAR(sum_quarters / sum_truth, 1.0, 0.02);
}

// Coverage of media rows (docs/rendering.md, "Coverage of eye segments"): a sample's first
// medium piece becomes one row for K film positions, each element sample integrating along one
// of their pieces. A sphere of fog under a distant light along the view axis, single scattering
// only and gathered by the rows (media_direct=0): its silhouette crosses pixels at every offset
// and its chord varies within each pixel. At one row per pixel, coverage comes close to K
// samples per pixel and far below one ray per row.
const char* kFogSphere = R"(
Integrator "volpath" "integer maxdepth" [ 1 ]
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ] "string filename" [ "fog.exr" ]
PixelFilter "box"
LookAt 0 0 6  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
WorldBegin
LightSource "distant" "point3 from" [ 0 0 6 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [ 0.2 0.2 0.2 ] "rgb sigma_s" [ 1.5 1.5 1.5 ] "float g" [ 0 ]
AttributeBegin
  MediumInterface "fog" ""
  Material "interface"
  Shape "sphere" "float radius" [ 1.1 ]
AttributeEnd
)";

RenderOutput RenderFog(const std::string& path, int spp, int segment_coverage) {
  return RenderBrute(path, spp, {"segment_coverage=" + std::to_string(segment_coverage), "media_direct=0"});
}

TEST(Coverage, MediaRowsAverageThePixelAtOneRowPerPixel) {
  TempDir dir;
  const std::string path = dir.Write("fog.pbrt", kFogSphere);
  constexpr int K = 16;
  const RenderOutput coverage = RenderFog(path, 1, K);
  const RenderOutput supersampled = RenderFog(path, K, 1);
  const RenderOutput single = RenderFog(path, 1, 1);
  const Image truth = RenderFog(path, 1024, 1).image;
  // The silhouette's radius in pixels (fov 30° over 32 pixels, the sphere 6 away): pixels whose
  // centre lies within 0.75 of it are partly covered.
  const double silhouette = std::tan(std::asin(1.1 / 6.0)) / std::tan(15.0 * double(kPi) / 180.0) * 16.0;
  double err_coverage = 0, err_supersampled = 0, err_single = 0, total = 0;
  double edge_coverage = 0, edge_supersampled = 0, edge_single = 0;
  int edge_pixels = 0;
  for (int y = 0; y < truth.height; ++y)
    for (int x = 0; x < truth.width; ++x) {
      const double t = Lum(truth.at(x, y));
      const double c = std::abs(Lum(coverage.image.at(x, y)) - t), s = std::abs(Lum(supersampled.image.at(x, y)) - t),
                   o = std::abs(Lum(single.image.at(x, y)) - t);
      total += t;
      err_coverage += c, err_supersampled += s, err_single += o;
      if (std::abs(std::hypot(x + 0.5 - 16.0, y + 0.5 - 16.0) - silhouette) < 0.75)
        ++edge_pixels, edge_coverage += c, edge_supersampled += s, edge_single += o;
    }
  std::printf("rel_l1: coverage %.4f, %d rays per pixel %.4f, one ray %.4f; on %d edge pixels: %.4f, %.4f, %.4f\n",
              err_coverage / total, K, err_supersampled / total, err_single / total, edge_pixels,
              edge_coverage / total, edge_supersampled / total, edge_single / total);
  EXPECT_GT(total, 0.0);
  EXPECT_GT(edge_pixels, 40);
  // The same element samples per pixel as one ray (16 for the distant light's column), closer
  // to the truth; on the silhouette, as close as K rays of as many samples each.
  EXPECT_LT(err_coverage, 0.7 * err_single);
  EXPECT_LT(edge_coverage, 0.4 * edge_single);
  EXPECT_LT(edge_coverage, 2.0 * edge_supersampled);
  // One row per sample that sees the fog from any of its positions, against K per pixel.
  const nlohmann::json& rc = coverage.stats["receivers"];
  const double rows = rc["segments"].get<double>(), pieces = rc["segment_pieces"].get<double>();
  EXPECT_EQ(rc["segment_coverage"].get<int>(), K);
  EXPECT_LE(rows, double(truth.width * truth.height));
  EXPECT_GT(pieces, 8 * rows);  // most rows are inside the silhouette: K pieces each
  EXPECT_LT(rows, 0.2 * supersampled.stats["receivers"]["segments"].get<double>());
  EXPECT_EQ(supersampled.stats["receivers"]["segment_pieces"].get<double>(), 0.0);
}

// The default coverage of media rows in a grid medium with virtual ray lights (multiple
// scattering through the rows' pieces) has the mean of many rays per pixel, the lights being the
// same: its estimator only averages the pixel's film positions.
TEST(Coverage, MediaRowsAreUnbiasedWithRayLightsInAGrid) {
  TempDir dir;
  const std::string path = dir.Write("grid.pbrt", R"(
Integrator "volpath" "integer maxdepth" [ 3 ]
Film "rgb" "integer xresolution" [ 24 ] "integer yresolution" [ 24 ] "string filename" [ "grid.exr" ]
PixelFilter "box"
LookAt 0 0 9  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
WorldBegin
LightSource "distant" "rgb L" [ 2 2 2 ] "point3 from" [ -1 2 1 ] "point3 to" [ 0 0 0 ]
AttributeBegin
  Translate -1.5 -1.5 -1.5
  Scale 3 3 3
  MakeNamedMedium "smoke" "string type" "uniformgrid" "integer nx" [ 4 ] "integer ny" [ 3 ] "integer nz" [ 2 ]
    "point3 p0" [ 0 0 0 ] "point3 p1" [ 1 1 1 ] "float g" [ 0.3 ]
    "rgb sigma_a" [ 0.1 0.1 0.1 ] "rgb sigma_s" [ 0.9 0.9 0.9 ]
    "float density" [ 0 1 2 1  1 2 0 1  0 1 1 0   1 0 2 1  2 1 1 0  0 0 1 1 ]
AttributeEnd
AttributeBegin
  MediumInterface "smoke" ""
  Material "interface"
  Shape "sphere" "float radius" [ 2.7 ]
AttributeEnd
)");
  double sum_cov = 0, sum_ref = 0;
  for (uint64_t seed = 0; seed < 4; ++seed) {
    RenderSettings s;
    s.method = "brute";
    s.lights = 300;
    s.seed = seed;
    s.spp = 1;
    s.params = {"camera_paths=0"};
    const RenderOutput cov = RenderScene(path, s);
    EXPECT_EQ(cov.stats["receivers"]["segment_coverage"].get<int>(), kDefaultSegmentCoverage);
    s.spp = 16;
    s.params = {"camera_paths=0", "segment_coverage=1"};
    const RenderOutput ref = RenderScene(path, s);
    for (int y = 0; y < cov.image.height; ++y)
      for (int x = 0; x < cov.image.width; ++x) {
        sum_cov += Lum(cov.image.at(x, y));
        sum_ref += Lum(ref.image.at(x, y));
      }
  }
  std::printf("image mean: coverage / 16 rays per pixel = %.5f\n", sum_cov / sum_ref);
  EXPECT_NEAR(sum_cov / sum_ref, 1.0, 0.005);
}

}  // namespace test_coverage
}  // namespace lightfarm
