// Lighting-matrix elements in media against high-order quadrature of their integrals: point
// light → eye segment (equi-angular sampling), medium VPL → eye segment (phase function at
// both ends), directional light → eye segment (transmittance sampling), medium VPL → surface
// point (phase function × BSDF, with the transmittance of the shadow segment).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "common/matrix/lighting_matrix.h"
#include "common/scene/phase.h"
#include "tests/common/fog_scene.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_media_segments {

constexpr float kSigmaA = 0.3f, kSigmaS = 0.9f, kG = 0.4f;

using testing::FogScene;  // tests/common/fog_scene.h

float SigmaT() { return kSigmaA + kSigmaS; }

// Quadrature of the segment integral for a point-like light of intensity I(w) at p.
template <typename IntensityFn>
double SegmentQuadrature(const EyeSegment& s, Vec3 p, IntensityFn intensity, bool directional,
                         Vec3 dir_to_light) {
  const int n = 400000;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    double t = (i + 0.5) / n * double(s.length);
    Vec3 y = s.o + s.d * float(t);
    Vec3 w;
    double g = 1, dist = 0;
    if (directional) {
      w = dir_to_light;
      // distance to the sphere boundary of radius 20 along w
      float b = Dot(y, w), c = LengthSquared(y) - 400.f;
      dist = double(-b + std::sqrt(b * b - c));
    } else {
      Vec3 d = p - y;
      dist = double(Length(d));
      w = d / float(dist);
      g = 1 / (dist * dist);
    }
    double v = double(kSigmaS) * std::exp(-double(SigmaT()) * t) *
               double(HenyeyGreenstein(Dot(w, s.d), kG)) * std::exp(-double(SigmaT()) * dist) *
               g * double(intensity(w));
    sum += v;
  }
  return sum * double(s.length) / n;
}

struct Fixture {
  std::unique_ptr<Scene> scene = FogScene();
  ReceiverSet receivers;
  LightSet lights;
};

// Mean of column 0 over the matrix's first `copies` rows (each seeded by its row), and its
// standard error.
struct MeanAndError {
  double mean = 0, error = 0;
};
MeanAndError MeanOverRows(const LightingMatrix& m, int copies) {
  MatrixCounters c;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < copies; ++i) {
    const double v = double(m.Element(uint32_t(i), 0, &c).g);
    sum += v;
    sum2 += v * v;
  }
  EXPECT_GT(c.transmittance_evals, 0u);
  const double mean = sum / copies;
  return {mean, std::sqrt(std::max(sum2 / copies - mean * mean, 0.0) / copies)};
}

// The element of `light` on `copies` identical segment rows.
MeanAndError MeanSegmentElement(Fixture& f, const EyeSegment& seg, const VirtualLight& light,
                                int copies, int samples) {
  f.receivers = ReceiverSet{};
  f.receivers.width = f.receivers.height = 1;
  f.receivers.samples.resize(1);
  for (int i = 0; i < copies; ++i) f.receivers.segments.push_back(seg);
  f.lights = LightSet{};
  f.lights.lights.push_back(light);
  MatrixOptions opt;
  opt.clamp = 0;
  opt.segment_samples = samples;
  LightingMatrix m(*f.scene, f.receivers, f.lights, opt);
  EXPECT_EQ(m.rows(), size_t(copies));
  return MeanOverRows(m, copies);
}

// Within 4 standard errors of the quadrature (plus 0.1% for float arithmetic against the double
// quadrature), and that precise: a bias of 1% cannot pass.
void ExpectMatches(const MeanAndError& got, double expect) {
  EXPECT_NEAR(got.mean, expect, 4 * got.error + 1e-3 * expect) << "got " << got.mean << " ± " << got.error;
  EXPECT_LT(got.error, 0.0025 * expect) << got.error;
}

EyeSegment TestSegment() {
  EyeSegment s;
  s.o = {-4, 1, 2};
  s.d = Normalize(Vec3{1, 0.2f, -0.3f});
  s.length = 7.5f;
  s.throughput = RGB(1.f);
  s.medium = 0;
  s.depth = 1;
  return s;
}

TEST(MediaElements, PointLightToSegment) {
  Fixture f;
  VirtualLight L;
  L.kind = VirtualLightKind::kPoint;
  L.p = {0.5f, 1.3f, 1.1f};  // 0.3 from the segment's line: a strong 1/d² peak
  L.power = RGB(2.f);
  EyeSegment s = TestSegment();
  double expect = SegmentQuadrature(s, L.p, [](Vec3) { return 2.f; }, false, {});
  ExpectMatches(MeanSegmentElement(f, s, L, 4096, 16), expect);
}

TEST(MediaElements, MediumVPLToSegment) {
  Fixture f;
  VirtualLight L;
  L.kind = VirtualLightKind::kMediumVPL;
  L.p = {-1, 3, 0};
  L.wi = Normalize(Vec3{0.3f, 1, 0.2f});
  L.power = RGB(5.f);
  L.g = 0.7f;
  L.medium = 0;
  L.depth = 1;
  EyeSegment s = TestSegment();
  auto intensity = [&](Vec3 w) { return 5.f * HenyeyGreenstein(Dot(L.wi, w), 0.7f); };
  double expect = SegmentQuadrature(s, L.p, intensity, false, {});
  ExpectMatches(MeanSegmentElement(f, s, L, 4096, 16), expect);
}

TEST(MediaElements, DirectionalLightToSegment) {
  Fixture f;
  VirtualLight L;
  L.kind = VirtualLightKind::kDirectional;
  L.n = Normalize(Vec3{0.2f, -1, 0.1f});  // travel direction
  L.power = RGB(3.f);
  EyeSegment s = TestSegment();
  double expect = SegmentQuadrature(s, {}, [](Vec3) { return 3.f; }, true, -L.n);
  ExpectMatches(MeanSegmentElement(f, s, L, 4096, 16), expect);
}

// A media row with coverage (EyeSegment::pieces): two of K = 5 film positions have a piece, each
// scaled by 2 / 5; a point light's element is the mean over the five positions of the pieces'
// integrals, its 16 stratified samples spread over the pieces.
TEST(MediaElements, PointLightToCoverageRow) {
  Fixture f;
  VirtualLight L;
  L.kind = VirtualLightKind::kPoint;
  L.p = {0.5f, 1.3f, 1.1f};
  L.power = RGB(2.f);
  EyeSegment a = TestSegment(), b = TestSegment();
  b.o = a.o + Vec3{0.2f, -0.5f, 0.3f};
  b.length = 5.f;
  const auto intensity = [](Vec3) { return 2.f; };
  const double expect = (SegmentQuadrature(a, L.p, intensity, false, {}) + SegmentQuadrature(b, L.p, intensity, false, {})) / 5;
  f.receivers.width = f.receivers.height = 1;
  f.receivers.samples.resize(1);
  f.receivers.segment_pieces = {a, b};
  for (EyeSegment& p : f.receivers.segment_pieces) p.throughput *= 2.f / 5.f;
  EyeSegment row = f.receivers.segment_pieces[0];
  row.pieces = 2;
  const int copies = 4096;
  for (int i = 0; i < copies; ++i) f.receivers.segments.push_back(row);
  f.lights.lights.push_back(L);
  MatrixOptions opt;
  opt.clamp = 0;
  opt.segment_samples = 16;
  LightingMatrix m(*f.scene, f.receivers, f.lights, opt);
  ExpectMatches(MeanOverRows(m, copies), expect);
}

// Point → point: closed form, no integral; the medium VPL's phase, the BSDF and the shadow
// segment's transmittance.
TEST(MediaElements, MediumVPLToSurfacePoint) {
  Fixture f;
  const auto& mats = f.scene->materials();
  uint32_t diffuse = 0;
  while (mats[diffuse].type != MaterialType::kDiffuse) ++diffuse;
  f.receivers.width = f.receivers.height = 1;
  f.receivers.samples.resize(1);
  ShadingPoint sp;
  sp.p = {0, 0, 0};
  sp.ng = sp.ns = {0, 1, 0};
  sp.wo = Normalize(Vec3{0, 1, 1});
  sp.throughput = RGB(1.f);
  sp.material = diffuse;
  sp.medium_out = sp.medium_in = 0;
  f.receivers.points.push_back(sp);
  VirtualLight L;
  L.kind = VirtualLightKind::kMediumVPL;
  L.p = {1, 2, -0.5f};
  L.wi = Normalize(Vec3{-1, 1, 0});
  L.power = RGB(4.f);
  L.g = -0.3f;
  L.medium = 0;
  L.depth = 1;
  f.lights.lights.push_back(L);
  MatrixOptions opt;
  opt.clamp = 0;
  LightingMatrix m(*f.scene, f.receivers, f.lights, opt);
  MatrixCounters c;
  float got = m.Element(0, 0, &c).g;
  Vec3 d = L.p - sp.p;
  float dist = Length(d);
  Vec3 w = d / dist;
  float expect = 0.5f / kPi * w.y * 4.f * HenyeyGreenstein(Dot(L.wi, w), -0.3f) *
                 std::exp(-SigmaT() * dist) / (dist * dist);
  EXPECT_NEAR(got, expect, 1e-3f * expect);
  EXPECT_EQ(c.transmittance_evals, 1u);
}

}  // namespace test_media_segments
}  // namespace lightfarm
