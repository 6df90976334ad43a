// Media rows and columns as pieces (docs/rendering.md, "Rows, columns and elements"): in a
// heterogeneous grid, the density-aware VRL → eye segment element (Huo 2016, Eq. 3) against
// quadrature of its double integral, and eye segments cut by AppendEyeSegments and VRL pieces
// cut by AppendVrlPieces summing, element by element, to the whole ray against the whole VRL;
// the same in a homogeneous fog; and the cuts' own invariants (contiguous, exact throughputs).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "common/render/render_job.h"
#include "common/lights/light_generation.h"
#include "common/matrix/lighting_matrix.h"
#include "common/scene/medium_track.h"
#include "common/scene/phase.h"
#include "tests/common/fog_scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_media_pieces {

// A 6×5×4 grid with empty cells and steep gradients in the world box [-2, 2]³, inside an
// interface sphere of radius 5 (the medium's boundary).
std::unique_ptr<Scene> GridScene() {
  SceneDescription desc = ParseSceneString(
      "Integrator \"volpath\" \"integer maxdepth\" [5]\n"
      "LookAt 0 0 50  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
      "AttributeBegin\nTranslate -2 -2 -2\nScale 4 4 4\n"
      "MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"integer nx\" [6] \"integer ny\" [5]\n"
      "  \"integer nz\" [4] \"point3 p0\" [0 0 0] \"point3 p1\" [1 1 1] \"float g\" [0.5]\n"
      "  \"rgb sigma_a\" [0.1 0.1 0.1] \"rgb sigma_s\" [0.8 0.8 0.8] \"float density\" [\n"
      "   0 0 1 2 0 0  0 1 3 2 1 0  1 2 0 0 2 1  0 1 2 3 1 0  0 0 1 1 0 0\n"
      "   0 1 2 1 0 0  1 3 4 2 1 0  2 0 0 1 3 1  1 2 3 2 2 0  0 1 1 0 0 0\n"
      "   0 0 2 3 1 0  1 2 0 0 2 1  2 3 1 0 4 2  0 1 2 3 0 0  0 0 0 1 1 0\n"
      "   0 0 0 1 0 0  0 1 2 1 0 0  1 1 0 0 1 1  0 0 1 2 1 0  0 0 0 0 0 0]\n"
      "AttributeEnd\n"
      "AttributeBegin\nMediumInterface \"smoke\" \"\"\nMaterial \"interface\"\n"
      "Shape \"sphere\" \"float radius\" [5]\nAttributeEnd\n",
      "grid.pbrt", "/tmp");
  return Scene::Build(desc, SceneBuildOptions{});
}

struct MeanAndError {
  double mean = 0, var = 0;  // var: of the mean
};

// Σ over the receivers' segments × the lights' columns of each element's mean over `copies`
// differently seeded copies of the segment, with the variance of that sum.
MeanAndError SumOfElements(const Scene& scene, const std::vector<EyeSegment>& segments,
                           const std::vector<VirtualLight>& lights, int copies, int samples) {
  ReceiverSet receivers;
  receivers.width = receivers.height = 1;
  receivers.samples.resize(1);
  for (const EyeSegment& s : segments)
    for (int c = 0; c < copies; ++c) receivers.segments.push_back(s);
  LightSet set;
  set.lights = lights;
  MatrixOptions opt;
  opt.clamp = 0.02f;
  opt.segment_samples = samples;
  LightingMatrix m(scene, receivers, set, opt);
  MatrixCounters counters;
  MeanAndError out;
  for (size_t si = 0; si < segments.size(); ++si)
    for (uint32_t j = 0; j < lights.size(); ++j) {
      double sum = 0, sum2 = 0;
      for (int c = 0; c < copies; ++c) {
        const double v = double(m.Element(uint32_t(si * size_t(copies) + size_t(c)), j, &counters).g);
        sum += v;
        sum2 += v * v;
      }
      const double mean = sum / copies;
      out.mean += mean;
      out.var += std::max(0.0, sum2 / copies - mean * mean) / (copies - 1);
    }
  return out;
}

// The element's double integral by the midpoint rule on an n × n grid: σ_s·Tr along both lines
// and the connection's transmittance from exact tracks, the clamped geometry term, both phases.
double Quadrature(const Scene& scene, const EyeSegment& seg, const VirtualLight& L, float clamp_distance, int n) {
  const Medium& med = scene.media().at(0);
  const MediumTrack eye(med, {seg.o, seg.d, seg.length}), light(med, {L.p, L.n, L.length});
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const float t = seg.length * (float(i) + 0.5f) / float(n);
    const MediumTrack::Point ep = eye.At(t);
    if (ep.sigma_s.IsBlack()) continue;
    const Vec3 x = seg.o + seg.d * t;
    for (int k = 0; k < n; ++k) {
      const float s = L.length * (float(k) + 0.5f) / float(n);
      const MediumTrack::Point lp = light.At(s);
      if (lp.sigma_s.IsBlack()) continue;
      const Vec3 y = L.p + L.n * s;
      const Vec3 d = y - x;
      const float dist2 = LengthSquared(d), dist = std::sqrt(dist2);
      const Vec3 w = d / dist;
      const MediumTrack conn(med, {x, w, dist});
      const double phase = double(HenyeyGreenstein(-Dot(L.n, w), L.g)) * double(HenyeyGreenstein(Dot(w, seg.d), med.g()));
      sum += double(ep.sigma_s.g * ep.tr.g) * double(lp.sigma_s.g * lp.tr.g) * phase *
             double(conn.TransmittanceToEnd().g) / double(std::max(dist2, clamp_distance * clamp_distance));
    }
  }
  return sum * double(seg.throughput.g) * double(L.power.g) * double(seg.length) * double(L.length) / (double(n) * n);
}

VirtualLight Vrl(const Scene& scene, Vec3 p, Vec3 d, float length) {
  VirtualLight L;
  L.kind = VirtualLightKind::kVRL;
  L.p = p;
  L.n = Normalize(d);
  L.ng = L.n;
  L.wi = -L.n;
  L.length = length;
  L.power = RGB(3.f);
  L.g = scene.media().at(0).g();
  L.medium = 0;
  L.depth = 1;
  return L;
}

// The whole eye ray (one segment) and the whole VRL (one piece), then both cut: the element sums
// agree with each other and with quadrature.
void ExpectPiecesSumToWhole(const Scene& scene, const Ray& eye, float eye_length, const VirtualLight& vrl,
                            float clamp_fraction) {
  const Medium& med = scene.media().at(0);
  std::vector<EyeSegment> whole_rows, cut_rows;
  AppendEyeSegments(med, 0, eye, eye_length, RGB(1.f), 0, 1, &whole_rows);
  AppendEyeSegments(med, 0, eye, eye_length, RGB(1.f), 7, 1, &cut_rows);
  std::vector<VirtualLight> whole_cols, cut_cols;
  ASSERT_TRUE(AppendVrlPieces(med, vrl, 1, &whole_cols));
  ASSERT_TRUE(AppendVrlPieces(med, vrl, 6, &cut_cols));
  ASSERT_EQ(whole_rows.size(), 1u);
  ASSERT_EQ(whole_cols.size(), 1u);
  ASSERT_GT(cut_rows.size(), 4u);
  ASSERT_GT(cut_cols.size(), 3u);
  const float clamp_distance = clamp_fraction * scene.bounds().Radius();
  const double expect = Quadrature(scene, whole_rows[0], whole_cols[0], clamp_distance, 600);
  ASSERT_GT(expect, 0.0);
  const MeanAndError whole = SumOfElements(scene, whole_rows, whole_cols, 16384, 8);
  const MeanAndError cut = SumOfElements(scene, cut_rows, cut_cols, 1024, 4);
  // Within 4 standard errors (plus 0.5% for the quadrature's own error), and precise enough that
  // a 5% bias could not pass.
  EXPECT_NEAR(whole.mean, expect, 4 * std::sqrt(whole.var) + 5e-3 * expect) << "whole";
  EXPECT_NEAR(cut.mean, expect, 4 * std::sqrt(cut.var) + 5e-3 * expect) << "cut";
  EXPECT_LT(std::sqrt(whole.var), 0.01 * expect);
  EXPECT_LT(std::sqrt(cut.var), 0.01 * expect);
}

TEST(MediaPieces, GridElementsAndPiecesMatchQuadrature) {
  auto scene = GridScene();
  ASSERT_FALSE(scene->media().at(0).homogeneous());
  const Ray eye{{-4.f, 0.3f, 0.4f}, Normalize(Vec3{1, -0.1f, -0.05f}), kInfinity};
  const VirtualLight vrl = Vrl(*scene, {0.5f, -3.f, -1.f}, {-0.2f, 1, 0.3f}, 6.f);
  ExpectPiecesSumToWhole(*scene, eye, 8.f, vrl, 0.01f);
}

TEST(MediaPieces, FogElementsAndPiecesMatchQuadrature) {
  auto scene = testing::FogScene();
  const Ray eye{{-4.f, 1.f, 2.f}, Normalize(Vec3{1, 0.2f, -0.3f}), kInfinity};
  const VirtualLight vrl = Vrl(*scene, {-1, 4, -2}, {0.2f, -1, 0.5f}, 6.f);
  ExpectPiecesSumToWhole(*scene, eye, 7.5f, vrl, 0.01f);
}

// The cuts: contiguous pieces inside the track's support, each segment's throughput the exact
// transmittance to its start, each piece's flux Φ·Tr(b→s_a); fewer pieces where light crosses.
TEST(MediaPieces, CutsAreContiguousWithExactThroughputs) {
  auto scene = GridScene();
  const Medium& med = scene->media().at(0);
  const Ray eye{{-4.f, 0.3f, 0.4f}, Normalize(Vec3{1, -0.1f, -0.05f}), kInfinity};
  const MediumTrack track(med, {eye.o, eye.d, 8.f});
  std::vector<EyeSegment> rows;
  const RGB tr = AppendEyeSegments(med, 0, eye, 8.f, RGB(2.f), 16, 1, &rows);
  EXPECT_NEAR(tr.g, track.TransmittanceToEnd().g, 1e-6f);
  ASSERT_FALSE(rows.empty());
  const int expect_n = int(std::ceil(17.f * (1.f - track.TransmittanceToEnd().Average())));
  EXPECT_EQ(int(rows.size()), expect_n);
  EXPECT_NEAR(Dot(rows.front().o - eye.o, eye.d), track.support_begin(), 1e-4f);
  float total = 0;
  for (size_t k = 0; k < rows.size(); ++k) {
    const float t0 = Dot(rows[k].o - eye.o, eye.d);
    EXPECT_NEAR(rows[k].throughput.g, 2.f * track.At(t0).tr.g, 1e-5f);
    if (k + 1 < rows.size()) {
      EXPECT_NEAR(t0 + rows[k].length, Dot(rows[k + 1].o - eye.o, eye.d), 1e-4f);
    }
    // Equal weight: each holds 1/n of the track's in-scattering (to the cdf's resolution inside
    // one interval), all of it together.
    const MediumTrack piece(med, {rows[k].o, rows[k].d, rows[k].length});
    const float w = piece.weight() * track.At(t0).tr.g;
    total += w;
    EXPECT_NEAR(w, track.weight() / float(rows.size()), 0.03f * track.weight() / float(rows.size()));
  }
  EXPECT_NEAR(total, track.weight(), 1e-3f * track.weight());
  // A ray through empty space makes no segment; a thin one fewer than h + 1.
  std::vector<EyeSegment> none;
  EXPECT_EQ(AppendEyeSegments(med, 0, {{-4.f, 3.f, 3.f}, {1, 0, 0}, kInfinity}, 8.f, RGB(1.f), 16, 1, &none).g, 1.f);
  EXPECT_TRUE(none.empty());
  std::vector<VirtualLight> pieces;
  const VirtualLight vrl = Vrl(*scene, {0.5f, -3.f, -1.f}, {-0.2f, 1, 0.3f}, 6.f);
  ASSERT_TRUE(AppendVrlPieces(med, vrl, 8, &pieces));
  const MediumTrack light(med, {vrl.p, vrl.n, vrl.length});
  for (const VirtualLight& p : pieces) {
    const float s0 = Dot(p.p - vrl.p, vrl.n);
    EXPECT_NEAR(p.power.g, vrl.power.g * light.At(s0).tr.g, 1e-5f);
    EXPECT_EQ(p.depth, vrl.depth);
  }
  std::vector<VirtualLight> empty_flight;
  EXPECT_FALSE(AppendVrlPieces(med, Vrl(*scene, {-4.f, 3.f, 3.f}, {1, 0, 0}, 8.f), 8, &empty_flight));
  EXPECT_TRUE(empty_flight.empty());
}

// A whole render, brute force: segment rows and piece columns with the emitters' single
// scattering on the camera side give the image whole rays and whole VRLs with the emitters'
// columns give, in expectation. The image means over 8 seeds each agree within 4 standard errors
// of their difference (each configuration's seed-to-seed spread measured here), and that bound is
// tight enough to see the emitters' single scattering counted twice or not at all.
TEST(MediaPieces, CutRowsPiecesAndCameraSideDirectLightGiveTheSameImage) {
  testing::TempDir dir;
  const std::string scene = dir.Write(
      "grid.pbrt",
      "Film \"rgb\" \"integer xresolution\" [12] \"integer yresolution\" [12]\n"
      "Integrator \"volpath\" \"integer maxdepth\" [3]\n"
      "LookAt 0 0 9  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [40]\nWorldBegin\n"
      "LightSource \"point\" \"rgb I\" [20 20 20] \"point3 from\" [2.5 3 1]\n"
      "LightSource \"distant\" \"rgb L\" [1 1 1] \"point3 from\" [-1 2 1] \"point3 to\" [0 0 0]\n"
      "AttributeBegin\nTranslate -2 -2 -2\nScale 4 4 4\n"
      "MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"integer nx\" [4] \"integer ny\" [3]\n"
      "  \"integer nz\" [2] \"point3 p0\" [0 0 0] \"point3 p1\" [1 1 1] \"float g\" [0.3]\n"
      "  \"rgb sigma_a\" [0.1 0.1 0.1] \"rgb sigma_s\" [0.9 0.9 0.9]\n"
      "  \"float density\" [0 1 2 1  1 2 0 1  0 1 1 0   1 0 2 1  2 1 1 0  0 0 1 1]\n"
      "AttributeEnd\n"
      "AttributeBegin\nMediumInterface \"smoke\" \"\"\nMaterial \"interface\"\n"
      "Shape \"sphere\" \"float radius\" [4]\nAttributeEnd\n");
  auto image_mean = [&](const std::vector<std::string>& params, uint64_t seed, nlohmann::json* stats) {
    RenderSettings s;
    s.lights = 400;
    s.seed = seed;
    s.params = params;
    s.params.push_back("segment_samples=4");
    const RenderOutput out = RenderScene(scene, s);
    if (stats) *stats = out.stats;
    double sum = 0;
    for (const RGB& p : out.image.pixels) sum += double(p.g);
    return sum / double(out.image.pixels.size());
  };
  const std::vector<std::string> whole = {"segments_per_ray=0", "vrl_pieces=1", "media_direct=0", "camera_paths=0"};
  const std::vector<std::string> cut = {"segments_per_ray=7", "vrl_pieces=6", "media_direct=2", "camera_paths=16"};
  double mean[2] = {0, 0}, var[2] = {0, 0};
  const int seeds = 8;
  nlohmann::json cut_stats;
  for (int c = 0; c < 2; ++c) {
    double sum = 0, sum2 = 0;
    for (int k = 0; k < seeds; ++k) {
      const double m = image_mean(c == 0 ? whole : cut, uint64_t(k + 1), c == 1 && k == 0 ? &cut_stats : nullptr);
      sum += m;
      sum2 += m * m;
    }
    mean[c] = sum / seeds;
    var[c] = std::max(0.0, sum2 / seeds - mean[c] * mean[c]) / (seeds - 1);
  }
  ASSERT_GT(mean[0], 0.0);
  EXPECT_NEAR(mean[1], mean[0], 4 * std::sqrt(var[0] + var[1])) << mean[0] << " vs " << mean[1];
  // What the cut configuration did: more rows than camera rays, more VRL columns than flights,
  // and camera paths carrying the emitters' single scattering.
  EXPECT_GT(cut_stats["receivers"]["segments"].get<uint64_t>(), cut_stats["receivers"]["camera_samples"].get<uint64_t>());
  EXPECT_GT(cut_stats["receivers"]["camera_paths"].get<uint64_t>(), 0u);
  EXPECT_GT(cut_stats["receivers"]["media_direct_samples"].get<uint64_t>(), 0u);
  EXPECT_GT(cut_stats["lights"]["vrl"].get<uint64_t>(), cut_stats["lights"]["vrl_flights"].get<uint64_t>());
  // and a grid medium's rows and columns are tabulated tracks, each with its cell-face knots.
  EXPECT_GT(cut_stats["media"]["tracks"].get<uint64_t>(), 0u);
  EXPECT_GT(cut_stats["media"]["track_knots"].get<uint64_t>(), cut_stats["media"]["tracks"].get<uint64_t>());
  // Twice or none of the emitters' single scattering would move the mean by far more than the
  // bound: it is a fifth of the image or more (one light budget: the emitters' columns alone),
  // the bound under a tenth.
  auto emitters_only = [&](const std::vector<std::string>& params) {
    RenderSettings s;
    s.lights = 1;
    s.spp = 16;
    s.params = params;
    double sum = 0;
    const RenderOutput out = RenderScene(scene, s);
    for (const RGB& p : out.image.pixels) sum += double(p.g);
    return sum / double(out.image.pixels.size());
  };
  const double single = emitters_only({"segments_per_ray=0", "media_direct=0", "camera_paths=0", "segment_samples=16"});
  EXPECT_GT(single, 0.2 * mean[0]);
  EXPECT_LT(4 * std::sqrt(var[0] + var[1]), 0.1 * mean[0]);
  // And the camera side carries it: with the emitters' columns alone (and 16 spp) the cut
  // configuration gives the same (measured 0.1% apart at 64 spp).
  EXPECT_NEAR(emitters_only({"segments_per_ray=7", "media_direct=16", "camera_paths=0"}), single, 0.03 * single);
}

}  // namespace test_media_pieces
}  // namespace lightfarm
