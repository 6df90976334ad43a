// Materials: reciprocity, energy conservation (white furnace), agreement between SampleBSDF,
// EvalBSDF and PdfBSDF, the specular lobes against independent formulas, robustness at
// grazing angles and extreme parameters, and CreateMaterial's parameter handling.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include "common/scene/bsdf.h"
#include "common/scene/params.h"
#include "common/util/error.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace test_bsdf {

constexpr TransportMode kRadiance = TransportMode::kRadiance;
constexpr TransportMode kImportance = TransportMode::kImportance;

// ---- Materials filled by hand -----------------------------------------------------------

Material Diffuse(RGB r) {
  Material m;
  m.type = MaterialType::kDiffuse;
  m.reflectance = r;
  return m;
}

// Copper, pbrt-v4's default conductor.
Material Conductor(float alpha_x, float alpha_y) {
  Material m;
  m.type = MaterialType::kConductor;
  m.eta = RGB(0.200438f, 0.924033f, 1.102212f);
  m.k = RGB(3.912949f, 2.452848f, 2.142188f);
  m.alpha_x = alpha_x;
  m.alpha_y = alpha_y;
  return m;
}

Material ReflectanceConductor(float reflectance, float alpha) {
  Material m;
  m.type = MaterialType::kConductor;
  m.conductor_uses_reflectance = true;
  m.reflectance = RGB(reflectance);
  m.alpha_x = m.alpha_y = alpha;
  return m;
}

Material Coated(RGB r, float alpha, float thickness = 0.01f, float eta = 1.5f) {
  Material m;
  m.type = MaterialType::kCoatedDiffuse;
  m.reflectance = r;
  m.alpha_x = m.alpha_y = alpha;
  m.thickness = thickness;
  m.eta = RGB(eta);
  return m;
}

Material Dielectric(float eta, float alpha) {
  Material m;
  m.type = MaterialType::kDielectric;
  m.eta = RGB(eta);
  m.alpha_x = m.alpha_y = alpha;
  return m;
}

Material ThinDielectric(float eta) {
  Material m;
  m.type = MaterialType::kThinDielectric;
  m.eta = RGB(eta);
  return m;
}

Material DiffuseTransmission(RGB r, RGB t) {
  Material m;
  m.type = MaterialType::kDiffuseTransmission;
  m.reflectance = r;
  m.transmittance = t;
  return m;
}

Material Interface() {
  Material m;
  m.type = MaterialType::kInterface;
  return m;
}

// ---- Directions and estimators ----------------------------------------------------------

// Unit direction with the given cos(theta) (sign chooses the side) and azimuth.
Vec3 Direction(float cos_theta, float phi) {
  float sin_theta = SafeSqrt(1 - Sqr(cos_theta));
  return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta};
}

Vec3 UniformSphere(Rng& rng) {
  float z = 1 - 2 * rng.Uniform();
  float r = SafeSqrt(1 - z * z);
  float phi = 2 * kPi * rng.Uniform();
  return {r * std::cos(phi), r * std::sin(phi), z};
}

Vec2 Uniform2D(Rng& rng) {
  float x = rng.Uniform();
  return {x, rng.Uniform()};
}

// Mean of f |cos| / pdf over SampleBSDF; with include_specular false only the non-delta
// samples count, which estimates the integral of the non-delta part of f.
RGB SampledAlbedo(const Material& m, Vec3 wo, TransportMode mode, int n, uint64_t seed,
                  bool include_specular = true) {
  Rng rng(seed);
  RGBAccum sum;
  for (int i = 0; i < n; ++i) {
    float uc = rng.Uniform();
    std::optional<BSDFSample> s = SampleBSDF(m, wo, uc, Uniform2D(rng), mode);
    if (!s || (s->IsSpecular() && !include_specular)) continue;
    sum.Add(s->f * (std::abs(s->wi.z) / s->pdf));
  }
  RGB total = sum.ToRGB();
  return total / static_cast<float>(n);
}

// Calls fn(wi) for n x n uniformly distributed directions on the sphere, jittered on a grid in
// (z, phi): stratification keeps peaked lobes from dominating the variance. Each direction
// stands for a solid angle of 4 pi / n^2.
template <typename Fn>
void ForStratifiedSphere(int n, uint64_t seed, Fn fn) {
  Rng rng(seed);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      float z = 1 - 2 * (i + rng.Uniform()) / n;
      float r = SafeSqrt(1 - z * z);
      float phi = 2 * kPi * (j + rng.Uniform()) / n;
      fn(Vec3(r * std::cos(phi), r * std::sin(phi), z));
    }
  }
}

// The integral of f |cos| by uniform (stratified) sampling of the sphere and EvalBSDF.
RGB UniformAlbedo(const Material& m, Vec3 wo, TransportMode mode, int n, uint64_t seed) {
  RGBAccum sum;
  ForStratifiedSphere(
      n, seed, [&](Vec3 wi) { sum.Add(EvalBSDF(m, wo, wi, mode) * (std::abs(wi.z) * 4 * kPi)); });
  RGB total = sum.ToRGB();
  return total / static_cast<float>(n * n);
}

float UniformPdfIntegral(const Material& m, Vec3 wo, int n, uint64_t seed) {
  double sum = 0;
  ForStratifiedSphere(n, seed, [&](Vec3 wi) { sum += double(PdfBSDF(m, wo, wi, kRadiance)); });
  return static_cast<float>(sum * 4 * 3.14159265358979323846 / (n * n));
}

bool NearRel(float a, float b, float rel, float abs_floor = 0) {
  return std::abs(a - b) <= rel * std::max(std::abs(a), std::abs(b)) + abs_floor;
}

struct NamedMaterial {
  std::string name;
  Material material;
  TransportMode mode = kRadiance;
};

// Materials with a non-delta part, rough enough for uniform sampling to converge.
std::vector<NamedMaterial> NonDeltaMaterials() {
  return {
      {"diffuse", Diffuse(RGB(0.8f, 0.5f, 0.2f))},
      {"conductor a=0.3", Conductor(0.3f, 0.3f)},
      {"conductor anisotropic", Conductor(0.2f, 0.6f)},
      {"conductor reflectance a=0.5", ReflectanceConductor(0.7f, 0.5f)},
      {"coated smooth", Coated(RGB(0.7f, 0.4f, 0.1f), 0)},
      {"coated a=0.3", Coated(RGB(0.7f, 0.4f, 0.1f), 0.3f)},
      {"coated a=1", Coated(RGB(0.9f), 1.f, 0.5f)},
      {"dielectric a=0.3 radiance", Dielectric(1.5f, 0.3f), kRadiance},
      {"dielectric a=0.3 importance", Dielectric(1.5f, 0.3f), kImportance},
      {"dielectric a=0.5 eta<1", Dielectric(0.8f, 0.5f), kRadiance},
      {"diffusetransmission", DiffuseTransmission(RGB(0.3f, 0.5f, 0.1f), RGB(0.6f, 0.2f, 0.4f))},
  };
}

// Outgoing directions on both sides, from normal to near-grazing.
std::vector<Vec3> TestDirections() {
  return {Direction(1.f, 0),    Direction(0.8f, 0.3f), Direction(0.4f, 2.f),
          Direction(0.1f, 4.f), Direction(-0.6f, 1.f), Direction(-0.2f, 5.f)};
}

// ---- Reciprocity --------------------------------------------------------------------------

void ExpectReciprocal(const Material& m, const std::string& name) {
  Rng rng(7);
  int checked = 0;
  for (int i = 0; i < 2000; ++i) {
    Vec3 wo = UniformSphere(rng), wi = UniformSphere(rng);
    if (wo.z * wi.z < 0) wi.z = -wi.z;  // reflection
    RGB a = EvalBSDF(m, wo, wi, kRadiance), b = EvalBSDF(m, wi, wo, kRadiance);
    for (int c = 0; c < 3; ++c)
      ASSERT_TRUE(NearRel(a[c], b[c], 1e-4f, 1e-7f))
          << name << " c=" << c << " f(wo,wi)=" << a[c] << " f(wi,wo)=" << b[c];
    if (a.Max() > 0) ++checked;
  }
  EXPECT_GT(checked, 500) << name << ": too few non-zero values to test";
}

TEST(BsdfReciprocity, ReflectionLobes) {
  ExpectReciprocal(Diffuse(RGB(0.3f, 0.6f, 0.9f)), "diffuse");
  ExpectReciprocal(Conductor(0.3f, 0.3f), "conductor");
  ExpectReciprocal(Conductor(0.05f, 0.5f), "conductor anisotropic");
  ExpectReciprocal(ReflectanceConductor(0.8f, 0.2f), "conductor reflectance");
  ExpectReciprocal(Coated(RGB(0.7f, 0.4f, 0.1f), 0), "coated smooth");
  ExpectReciprocal(Coated(RGB(0.7f, 0.4f, 0.1f), 0.4f, 0.3f), "coated rough");
  ExpectReciprocal(Dielectric(1.5f, 0.4f), "dielectric reflection");
  ExpectReciprocal(DiffuseTransmission(RGB(0.3f), RGB(0.5f)), "diffusetransmission");
}

// Refraction is not symmetric in radiance units; the Importance-mode BSDF is the adjoint:
// f_radiance(wo, wi) = f_importance(wi, wo) (Veach 1997, Sec. 5.2).
TEST(BsdfReciprocity, RoughDielectricTransmissionIsAdjoint) {
  Material m = Dielectric(1.5f, 0.4f);
  Rng rng(11);
  int checked = 0;
  for (int i = 0; i < 2000; ++i) {
    Vec3 wo = UniformSphere(rng), wi = UniformSphere(rng);
    if (wo.z * wi.z > 0) wi.z = -wi.z;  // transmission
    float radiance = EvalBSDF(m, wo, wi, kRadiance).r;
    float importance = EvalBSDF(m, wi, wo, kImportance).r;
    // Float rounding in the half vector shows in the far tails: a loose relative tolerance
    // still catches a missing 1/eta^2 (a factor 2.25) or a wrong Jacobian
    ASSERT_TRUE(NearRel(radiance, importance, 5e-3f, 1e-6f))
        << "wo.z=" << wo.z << " wi.z=" << wi.z << " " << radiance << " vs " << importance;
    if (radiance > 0) ++checked;
  }
  EXPECT_GT(checked, 300);
}

// ---- Energy -------------------------------------------------------------------------------

TEST(BsdfEnergy, DiffuseAlbedoEqualsReflectance) {
  Material m = Diffuse(RGB(0.5f));
  for (Vec3 wo : TestDirections()) {
    RGB a = SampledAlbedo(m, wo, kRadiance, 200000, 1);
    EXPECT_NEAR(a.g, 0.5f, 0.005f) << "wo.z=" << wo.z;
    EXPECT_NEAR(UniformAlbedo(m, wo, kRadiance, 300, 2).g, 0.5f, 0.005f) << "wo.z=" << wo.z;
  }
}

TEST(BsdfEnergy, WhiteFurnaceNeverExceedsOne) {
  // Dielectrics in Importance mode: Radiance mode scales refraction by 1/eta^2 on purpose.
  std::vector<NamedMaterial> materials = {
      {"diffuse", Diffuse(RGB(1.f))},
      {"conductor smooth", ReflectanceConductor(1.f, 0)},
      {"conductor a=0.1", ReflectanceConductor(1.f, 0.1f)},
      {"conductor a=1", ReflectanceConductor(1.f, 1.f)},
      {"conductor anisotropic", ReflectanceConductor(1.f, 0)},
      {"copper a=0.5", Conductor(0.5f, 0.5f)},
      {"coated smooth", Coated(RGB(1.f), 0, 0)},
      {"coated a=0.3", Coated(RGB(1.f), 0.3f, 0)},
      {"coated a=1", Coated(RGB(1.f), 1.f, 0)},
      {"coated eta=2.5", Coated(RGB(1.f), 0.2f, 0, 2.5f)},
      {"dielectric smooth", Dielectric(1.5f, 0), kImportance},
      {"dielectric a=0.3", Dielectric(1.5f, 0.3f), kImportance},
      {"dielectric a=1", Dielectric(1.5f, 1.f), kImportance},
      {"dielectric eta=1", Dielectric(1.f, 0.5f), kImportance},
      {"thindielectric", ThinDielectric(1.5f)},
      {"diffusetransmission", DiffuseTransmission(RGB(0.6f), RGB(0.4f))},
  };
  materials[4].material.alpha_x = 0.05f;
  materials[4].material.alpha_y = 0.8f;
  for (const NamedMaterial& nm : materials) {
    for (Vec3 wo : TestDirections()) {
      RGB a = SampledAlbedo(nm.material, wo, nm.mode, 50000, 3);
      EXPECT_LE(a.Max(), 1.01f) << nm.name << " wo.z=" << wo.z;
      EXPECT_GT(a.Max(), 0.3f) << nm.name << " wo.z=" << wo.z;  // and not absurdly lossy
    }
  }
}

TEST(BsdfEnergy, PerfectRoughMirrorConservesEnergy) {
  RGB a = SampledAlbedo(ReflectanceConductor(1.f, 0.1f), Vec3(0, 0, 1), kRadiance, 200000, 4);
  EXPECT_GE(a.g, 0.9f);
  EXPECT_LE(a.g, 1.001f);
}

// A coat over a white base without absorption: the coat reflects E(wo) and the base returns
// everything else (the internal diffuse reflectance makes the geometric series sum to exactly
// 1 - E(wo)); a wrong F_dr,int or rough-coat albedo table would break this at every angle.
TEST(BsdfEnergy, LosslessCoatedDiffuseReflectsEverything) {
  std::vector<Material> coats = {Coated(RGB(1.f), 0, 0, 1.33f),   Coated(RGB(1.f), 0, 0, 1.5f),
                                 Coated(RGB(1.f), 0, 0, 2.f),     Coated(RGB(1.f), 0.1f, 0, 1.5f),
                                 Coated(RGB(1.f), 0.5f, 0, 1.5f), Coated(RGB(1.f), 1.f, 0, 1.8f),
                                 Coated(RGB(1.f), 0.05f, 0, 1.5f)};
  coats.back().alpha_y = 0.6f;  // anisotropic
  for (size_t i = 0; i < coats.size(); ++i) {
    for (float cos_o : {1.f, 0.6f, 0.2f, 0.05f}) {
      RGB a = SampledAlbedo(coats[i], Direction(cos_o, 0.5f), kRadiance, 50000, 5);
      EXPECT_NEAR(a.g, 1.f, 0.01f) << "coat " << i << " cos_o=" << cos_o;
    }
  }
  // The default thickness absorbs a little
  Material thick = Coated(RGB(1.f), 0, 0.01f);
  float normal = SampledAlbedo(thick, Vec3(0, 0, 1), kRadiance, 50000, 6).g;
  EXPECT_LT(normal, 0.995f);
  EXPECT_GT(normal, 0.97f);
}

// ---- Sampling consistency ------------------------------------------------------------------

TEST(BsdfSampling, ImportanceSamplingMatchesUniformSampling) {
  for (const NamedMaterial& nm : NonDeltaMaterials()) {
    for (Vec3 wo : TestDirections()) {
      RGB sampled = SampledAlbedo(nm.material, wo, nm.mode, 60000, 8, false);
      RGB uniform = UniformAlbedo(nm.material, wo, nm.mode, 300, 9);
      for (int c = 0; c < 3; ++c)
        EXPECT_TRUE(NearRel(sampled[c], uniform[c], 0.03f, 0.003f))
            << nm.name << " wo.z=" << wo.z << " c=" << c << " sampled=" << sampled[c]
            << " uniform=" << uniform[c];
    }
  }
}

TEST(BsdfSampling, SampleAgreesWithEvalAndPdf) {
  for (const NamedMaterial& nm : NonDeltaMaterials()) {
    for (Vec3 wo : TestDirections()) {
      Rng rng(10);
      int non_specular = 0;
      for (int i = 0; i < 5000; ++i) {
        float uc = rng.Uniform();
        std::optional<BSDFSample> s = SampleBSDF(nm.material, wo, uc, Uniform2D(rng), nm.mode);
        if (!s || s->IsSpecular()) continue;
        ++non_specular;
        float pdf = PdfBSDF(nm.material, wo, s->wi, nm.mode);
        ASSERT_TRUE(NearRel(pdf, s->pdf, 1e-3f))
            << nm.name << " wo.z=" << wo.z << " Pdf=" << pdf << " sample pdf=" << s->pdf;
        RGB f = EvalBSDF(nm.material, wo, s->wi, nm.mode);
        for (int c = 0; c < 3; ++c)
          ASSERT_TRUE(NearRel(f[c], s->f[c], 1e-3f, 1e-8f))
              << nm.name << " wo.z=" << wo.z << " Eval=" << f[c] << " sample f=" << s->f[c];
        ASSERT_NEAR(Length(s->wi), 1.f, 1e-4f);
        // The sampled lobe's side matches its flag
        bool transmitted = s->wi.z * wo.z < 0;
        EXPECT_EQ(transmitted, (s->flags & kBxDFTransmission) != 0) << nm.name;
      }
      EXPECT_GT(non_specular, 1000) << nm.name << " wo.z=" << wo.z;
    }
  }
}

TEST(BsdfSampling, PdfIntegratesToAtMostOne) {
  for (const NamedMaterial& nm : NonDeltaMaterials()) {
    for (Vec3 wo : TestDirections()) {
      float integral = UniformPdfIntegral(nm.material, wo, 300, 12);
      EXPECT_LE(integral, 1.02f) << nm.name << " wo.z=" << wo.z;
      if (nm.name == "diffuse" || nm.name == "diffusetransmission") {
        EXPECT_NEAR(integral, 1.f, 0.01f) << nm.name << " wo.z=" << wo.z;
      }
    }
  }
}

// ---- Specular lobes against independent formulas --------------------------------------------

// Fresnel reflectance of a conductor from the s- and p-polarised amplitudes written with
// cos_t' = sqrt(n^2 - sin^2) (Born & Wolf form), in double precision.
double IndependentConductorFresnel(double cos_i, double eta, double k) {
  using C = std::complex<double>;
  C n(eta, k);
  double sin2 = 1 - cos_i * cos_i;
  C root = std::sqrt(n * n - sin2);
  C rs = (cos_i - root) / (cos_i + root);
  C rp = (n * n * cos_i - root) / (n * n * cos_i + root);
  return 0.5 * (std::norm(rs) + std::norm(rp));
}

TEST(BsdfConductor, SmoothIsAFresnelMirror) {
  Material m = Conductor(0, 0);
  EXPECT_EQ(MaterialFlags(m), uint32_t(kBxDFReflection | kBxDFSpecular));
  // Normal incidence: ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2)
  std::optional<BSDFSample> s = SampleBSDF(m, Vec3(0, 0, 1), 0.3f, Vec2(0.2f, 0.7f), kRadiance);
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->IsSpecular());
  for (int c = 0; c < 3; ++c) {
    double n = m.eta[c], k = m.k[c];
    double expected = ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k);
    EXPECT_NEAR(s->f[c] * std::abs(s->wi.z) / s->pdf, expected, 1e-5) << "c=" << c;
  }
  for (Vec3 wo : TestDirections()) {
    s = SampleBSDF(m, wo, 0.5f, Vec2(0.5f, 0.5f), kRadiance);
    ASSERT_TRUE(s);
    EXPECT_NEAR(s->wi.x, -wo.x, 1e-6f);
    EXPECT_NEAR(s->wi.y, -wo.y, 1e-6f);
    EXPECT_NEAR(s->wi.z, wo.z, 1e-6f);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(s->f[c] * std::abs(s->wi.z) / s->pdf,
                  IndependentConductorFresnel(std::abs(wo.z), m.eta[c], m.k[c]), 1e-4)
          << "wo.z=" << wo.z << " c=" << c;
    // Delta lobes are invisible to Eval and Pdf
    EXPECT_TRUE(EvalBSDF(m, wo, s->wi, kRadiance).IsBlack());
    EXPECT_EQ(PdfBSDF(m, wo, s->wi, kRadiance), 0.f);
  }
}

TEST(BsdfConductor, ReflectanceIsNormalIncidenceFresnel) {
  for (float r : {0.f, 0.25f, 0.9f}) {
    std::optional<BSDFSample> s =
        SampleBSDF(ReflectanceConductor(r, 0), Vec3(0, 0, 1), 0.5f, Vec2(0.5f, 0.5f), kRadiance);
    ASSERT_TRUE(s);
    EXPECT_NEAR(s->f.r * s->wi.z / s->pdf, r, 1e-4f);
  }
}

// Specular sample of a smooth dielectric with a given lobe forced by uc.
BSDFSample DielectricSample(float eta, Vec3 wo, bool reflect, TransportMode mode) {
  std::optional<BSDFSample> s =
      SampleBSDF(Dielectric(eta, 0), wo, reflect ? 0.f : 0.999999f, Vec2(0.5f, 0.5f), mode);
  EXPECT_TRUE(s);
  return s.value_or(BSDFSample{});
}

TEST(BsdfDielectric, RefractionObeysSnellsLaw) {
  const float eta = 1.5f;
  for (Vec3 wo : TestDirections()) {
    if (wo.z < 0 && 1 - Sqr(wo.z) > 1 / Sqr(eta)) continue;  // TIR: tested below
    BSDFSample s = DielectricSample(eta, wo, false, kImportance);
    ASSERT_TRUE(s.flags & kBxDFTransmission) << "wo.z=" << wo.z;
    EXPECT_LT(s.wi.z * wo.z, 0) << "wo.z=" << wo.z;
    // eta_o sin_o = eta_i sin_i, and the tangential parts point in opposite directions
    float eta_o = wo.z > 0 ? 1.f : eta, eta_i = wo.z > 0 ? eta : 1.f;
    EXPECT_NEAR(s.wi.x * eta_i, -wo.x * eta_o, 1e-5f) << "wo.z=" << wo.z;
    EXPECT_NEAR(s.wi.y * eta_i, -wo.y * eta_o, 1e-5f) << "wo.z=" << wo.z;
    EXPECT_NEAR(Length(s.wi), 1.f, 1e-5f);
    EXPECT_NEAR(s.eta, eta_i / eta_o, 1e-6f);
  }
}

TEST(BsdfDielectric, TotalInternalReflectionOnlyReflects) {
  const float eta = 1.5f;           // critical angle: sin = 1/1.5, cos = 0.745
  Vec3 wo = Direction(-0.5f, 1.f);  // inside, beyond the critical angle
  Rng rng(13);
  for (int i = 0; i < 1000; ++i) {
    std::optional<BSDFSample> s =
        SampleBSDF(Dielectric(eta, 0), wo, rng.Uniform(), Uniform2D(rng), kRadiance);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->flags, uint32_t(kBxDFReflection | kBxDFSpecular));
    EXPECT_NEAR(s->wi.z, wo.z, 1e-6f);
    EXPECT_NEAR(s->f.r * std::abs(s->wi.z) / s->pdf, 1.f, 1e-6f);
  }
  // Just inside the critical angle transmission is possible again
  BSDFSample t = DielectricSample(eta, Direction(-0.76f, 1.f), false, kRadiance);
  EXPECT_TRUE(t.flags & kBxDFTransmission);
}

TEST(BsdfDielectric, ReflectionAndTransmissionSumToOne) {
  const float eta = 1.5f;
  for (Vec3 wo : TestDirections()) {
    if (wo.z < 0 && 1 - Sqr(wo.z) > 1 / Sqr(eta)) continue;  // TIR: tested above
    BSDFSample r = DielectricSample(eta, wo, true, kImportance);
    BSDFSample t = DielectricSample(eta, wo, false, kImportance);
    ASSERT_TRUE(r.flags & kBxDFReflection);
    ASSERT_TRUE(t.flags & kBxDFTransmission);
    float fr = r.f.r * std::abs(r.wi.z), ft = t.f.r * std::abs(t.wi.z);
    EXPECT_NEAR(fr + ft, 1.f, 1e-5f) << "wo.z=" << wo.z;
    EXPECT_NEAR(r.pdf + t.pdf, 1.f, 1e-6f);
    // Each lobe's weight f |cos| / pdf is 1: the lobe choice is proportional to R and T
    EXPECT_NEAR(fr / r.pdf, 1.f, 1e-5f);
    EXPECT_NEAR(ft / t.pdf, 1.f, 1e-5f);
    // Radiance mode divides transmitted radiance by eta_t^2 / eta_i^2
    BSDFSample tr = DielectricSample(eta, wo, false, kRadiance);
    EXPECT_NEAR(tr.f.r * std::abs(tr.wi.z), ft / Sqr(tr.eta), 1e-5f);
  }
  // Normal incidence: R = ((eta - 1) / (eta + 1))^2
  BSDFSample r = DielectricSample(eta, Vec3(0, 0, 1), true, kImportance);
  EXPECT_NEAR(r.f.r * r.wi.z, 0.04f, 1e-6f);
}

TEST(BsdfDielectric, IndexMatchedPassesStraightThrough) {
  for (float alpha : {0.f, 0.5f}) {
    Material m = Dielectric(1.f, alpha);
    EXPECT_EQ(MaterialFlags(m), uint32_t(kBxDFTransmission | kBxDFSpecular));
    for (Vec3 wo : TestDirections()) {
      std::optional<BSDFSample> s = SampleBSDF(m, wo, 0.f, Vec2(0.3f, 0.3f), kRadiance);
      ASSERT_TRUE(s);
      EXPECT_EQ(s->wi, -wo);
      EXPECT_NEAR(s->f.r * std::abs(s->wi.z) / s->pdf, 1.f, 1e-6f);
      EXPECT_TRUE(EvalBSDF(m, wo, -wo, kRadiance).IsBlack());
    }
  }
}

TEST(BsdfThinDielectric, InterReflectionWithoutBending) {
  Material m = ThinDielectric(1.5f);
  // R = 0.04 at normal incidence; R' = R + T^2 R / (1 - R^2) = 2R / (1 + R)
  const float expected_r = 2 * 0.04f / 1.04f;
  Vec3 wo(0, 0, 1);
  std::optional<BSDFSample> r = SampleBSDF(m, wo, 0.f, Vec2(), kRadiance);
  std::optional<BSDFSample> t = SampleBSDF(m, wo, 0.99f, Vec2(), kRadiance);
  ASSERT_TRUE(r && t);
  EXPECT_NEAR(r->f.r * r->wi.z, expected_r, 1e-6f);
  EXPECT_NEAR(r->pdf, expected_r, 1e-6f);
  EXPECT_NEAR(t->f.r * std::abs(t->wi.z), 1 - expected_r, 1e-6f);
  for (Vec3 w : TestDirections()) {
    std::optional<BSDFSample> s = SampleBSDF(m, w, 0.999f, Vec2(), kRadiance);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->wi, -w);
    EXPECT_EQ(s->eta, 1.f);
  }
}

TEST(BsdfDiffuseTransmission, ReflectsOnTheSideOfWoTransmitsToTheOther) {
  Material m = DiffuseTransmission(RGB(0.2f), RGB(0.6f));
  for (float side : {1.f, -1.f}) {
    Vec3 wo = Direction(0.5f * side, 0.2f);
    EXPECT_NEAR(EvalBSDF(m, wo, Direction(0.3f * side, 2.f), kRadiance).r, 0.2f * kInvPi, 1e-7f);
    EXPECT_NEAR(EvalBSDF(m, wo, Direction(-0.3f * side, 2.f), kRadiance).r, 0.6f * kInvPi, 1e-7f);
    EXPECT_NEAR(SampledAlbedo(m, wo, kRadiance, 20000, 14).r, 0.8f, 1e-4f);
  }
}

TEST(BsdfInterface, HasNoLobes) {
  Material m = Interface();
  EXPECT_EQ(MaterialFlags(m), 0u);
  EXPECT_TRUE(IsPurelySpecular(MaterialFlags(m)));
  EXPECT_TRUE(EvalBSDF(m, Vec3(0, 0, 1), Vec3(0, 0, 1), kRadiance).IsBlack());
  EXPECT_EQ(PdfBSDF(m, Vec3(0, 0, 1), Vec3(0, 0, 1), kRadiance), 0.f);
  EXPECT_FALSE(SampleBSDF(m, Vec3(0, 0, 1), 0.5f, Vec2(0.5f, 0.5f), kRadiance));
}

TEST(BsdfFlags, UnionOfLobes) {
  EXPECT_EQ(MaterialFlags(Diffuse(RGB(0.5f))), uint32_t(kBxDFReflection | kBxDFDiffuse));
  // A black diffuse surface is still an opaque surface, not a pass-through interface
  EXPECT_EQ(MaterialFlags(Diffuse(RGB(0.f))), uint32_t(kBxDFReflection | kBxDFDiffuse));
  EXPECT_EQ(MaterialFlags(Conductor(0.2f, 0.2f)), uint32_t(kBxDFReflection | kBxDFGlossy));
  EXPECT_EQ(MaterialFlags(Conductor(1e-4f, 1e-4f)), uint32_t(kBxDFReflection | kBxDFSpecular));
  EXPECT_EQ(MaterialFlags(Conductor(1e-4f, 0.3f)), uint32_t(kBxDFReflection | kBxDFGlossy));
  EXPECT_EQ(MaterialFlags(Coated(RGB(0.5f), 0)),
            uint32_t(kBxDFReflection | kBxDFDiffuse | kBxDFSpecular));
  EXPECT_EQ(MaterialFlags(Coated(RGB(0.5f), 0.1f)),
            uint32_t(kBxDFReflection | kBxDFDiffuse | kBxDFGlossy));
  EXPECT_EQ(MaterialFlags(Dielectric(1.5f, 0)),
            uint32_t(kBxDFReflection | kBxDFTransmission | kBxDFSpecular));
  EXPECT_EQ(MaterialFlags(Dielectric(1.5f, 0.1f)),
            uint32_t(kBxDFReflection | kBxDFTransmission | kBxDFGlossy));
  EXPECT_EQ(MaterialFlags(ThinDielectric(1.5f)),
            uint32_t(kBxDFReflection | kBxDFTransmission | kBxDFSpecular));
  EXPECT_EQ(MaterialFlags(DiffuseTransmission(RGB(0.2f), RGB(0.3f))),
            uint32_t(kBxDFReflection | kBxDFTransmission | kBxDFDiffuse));
  EXPECT_EQ(MaterialFlags(DiffuseTransmission(RGB(0.f), RGB(0.3f))),
            uint32_t(kBxDFTransmission | kBxDFDiffuse));
  EXPECT_TRUE(IsPurelySpecular(MaterialFlags(Dielectric(1.5f, 0))));
  EXPECT_FALSE(IsPurelySpecular(MaterialFlags(Coated(RGB(0.5f), 0))));
}

// ---- Robustness ---------------------------------------------------------------------------

TEST(BsdfRobustness, NoNaNOrInfAtExtremes) {
  std::vector<Material> materials = {
      Diffuse(RGB(1.f)),
      Conductor(0, 0),
      Conductor(1e-5f, 1e-5f),
      Conductor(1e-3f, 1e-3f),
      Conductor(1e-5f, 1.f),
      Conductor(1.f, 1.f),
      ReflectanceConductor(0.f, 0.3f),
      ReflectanceConductor(1.f, 1e-3f),
      Coated(RGB(1.f), 0),
      Coated(RGB(1.f), 1e-3f),
      Coated(RGB(1.f), 1.f, 10.f),
      Coated(RGB(0.f), 0.5f),
      Coated(RGB(0.5f), 0.2f, 0.01f, 1.f),
      Coated(RGB(0.5f), 0.2f, 0.01f, 0.7f),
      Dielectric(1.5f, 0),
      Dielectric(1.5f, 1e-5f),
      Dielectric(1.5f, 1e-3f),
      Dielectric(1.5f, 1.f),
      Dielectric(1.f, 0),
      Dielectric(1.f, 0.5f),
      Dielectric(1.0001f, 0.5f),
      Dielectric(0.5f, 0.3f),
      ThinDielectric(1.5f),
      ThinDielectric(1.f),
      DiffuseTransmission(RGB(0.f), RGB(0.f)),
      DiffuseTransmission(RGB(1.f), RGB(0.f)),
  };
  const float g = 1e-7f;
  std::vector<Vec3> wos = {Vec3(0, 0, 1),
                           Vec3(0, 0, -1),
                           Vec3(1, 0, 0),
                           Vec3(0, 1, 0),
                           Vec3(SafeSqrt(1 - g * g), 0, g),
                           Vec3(0, SafeSqrt(1 - g * g), -g),
                           Direction(0.5f, 1.f),
                           Direction(1e-4f, 3.f)};
  Rng rng(15);
  for (size_t mi = 0; mi < materials.size(); ++mi) {
    const Material& m = materials[mi];
    for (Vec3 wo : wos) {
      std::vector<Vec3> wis = {wo,
                               -wo,
                               Vec3(-wo.x, -wo.y, wo.z),
                               Vec3(0, 0, 1),
                               Vec3(0, 0, -1),
                               Vec3(1, 0, 0),
                               Vec3(-wo.x, -wo.y, -wo.z)};
      for (int i = 0; i < 200; ++i) wis.push_back(UniformSphere(rng));
      for (TransportMode mode : {kRadiance, kImportance}) {
        for (Vec3 wi : wis) {
          RGB f = EvalBSDF(m, wo, wi, mode);
          float pdf = PdfBSDF(m, wo, wi, mode);
          ASSERT_TRUE(f.IsFinite() && f.r >= 0 && f.g >= 0 && f.b >= 0)
              << "material " << mi << " wo.z=" << wo.z << " wi.z=" << wi.z;
          ASSERT_TRUE(std::isfinite(pdf) && pdf >= 0) << "material " << mi;
        }
        for (int i = 0; i < 500; ++i) {
          float uc = rng.Uniform();
          std::optional<BSDFSample> s = SampleBSDF(m, wo, uc, Uniform2D(rng), mode);
          if (!s) continue;
          ASSERT_TRUE(s->f.IsFinite() && s->f.r >= 0 && s->f.g >= 0 && s->f.b >= 0)
              << "material " << mi << " wo.z=" << wo.z;
          ASSERT_TRUE(std::isfinite(s->pdf) && s->pdf > 0) << "material " << mi;
          ASSERT_TRUE(IsFinite(s->wi) && s->wi.z != 0) << "material " << mi;
          ASSERT_NEAR(Length(s->wi), 1.f, 1e-3f) << "material " << mi;
          ASSERT_TRUE(std::isfinite(s->eta) && s->eta > 0);
        }
      }
    }
  }
}

// ---- CreateMaterial --------------------------------------------------------------------------

Param FloatParam(const std::string& name, double v) {
  Param p;
  p.type = "float";
  p.name = name;
  p.numbers = {v};
  return p;
}
Param RGBParam(const std::string& name, double r, double g, double b) {
  Param p;
  p.type = "rgb";
  p.name = name;
  p.numbers = {r, g, b};
  return p;
}
Param BoolParam(const std::string& name, bool v) {
  Param p;
  p.type = "bool";
  p.name = name;
  p.bools = {v};
  return p;
}
Param StringParam(const std::string& type, const std::string& name, const std::string& v) {
  Param p;
  p.type = type;
  p.name = name;
  p.strings = {v};
  return p;
}

MaterialDesc Desc(const std::string& type, std::vector<Param> params = {}) {
  MaterialDesc desc;
  desc.type = type;
  desc.loc = FileLoc{"scene.pbrt", 12, 1};
  for (Param& p : params) {
    p.loc = FileLoc{"scene.pbrt", 13, 5};
    desc.params.Add(std::move(p));
  }
  return desc;
}

std::string CreateError(const MaterialDesc& desc) {
  try {
    CreateMaterial(desc);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(CreateMaterial, Defaults) {
  Material d = CreateMaterial(Desc("diffuse"));
  EXPECT_EQ(d.type, MaterialType::kDiffuse);
  EXPECT_EQ(d.reflectance, RGB(0.5f));

  Material c = CreateMaterial(Desc("conductor"));
  EXPECT_EQ(c.type, MaterialType::kConductor);
  EXPECT_EQ(c.eta, RGB(0.200438f, 0.924033f, 1.102212f));
  EXPECT_EQ(c.k, RGB(3.912949f, 2.452848f, 2.142188f));
  EXPECT_FALSE(c.conductor_uses_reflectance);
  EXPECT_EQ(c.alpha_x, 0.f);
  EXPECT_EQ(MaterialFlags(c), uint32_t(kBxDFReflection | kBxDFSpecular));

  Material g = CreateMaterial(Desc("dielectric"));
  EXPECT_EQ(g.type, MaterialType::kDielectric);
  EXPECT_EQ(g.eta.r, 1.5f);

  Material cd = CreateMaterial(Desc("coateddiffuse"));
  EXPECT_EQ(cd.type, MaterialType::kCoatedDiffuse);
  EXPECT_EQ(cd.reflectance, RGB(0.5f));
  EXPECT_EQ(cd.thickness, 0.01f);
  EXPECT_EQ(cd.eta.r, 1.5f);
  EXPECT_EQ(cd.coat_albedo, RGB(0.f));

  Material dt = CreateMaterial(Desc("diffusetransmission"));
  EXPECT_EQ(dt.reflectance, RGB(0.25f));
  EXPECT_EQ(dt.transmittance, RGB(0.25f));
  Material scaled = CreateMaterial(Desc("diffusetransmission", {FloatParam("scale", 2)}));
  EXPECT_EQ(scaled.reflectance, RGB(0.5f));
  EXPECT_EQ(scaled.transmittance, RGB(0.5f));

  EXPECT_EQ(CreateMaterial(Desc("thindielectric")).eta.r, 1.5f);
  EXPECT_EQ(MaterialFlags(CreateMaterial(Desc("interface"))), 0u);
}

TEST(CreateMaterial, ReadsParameters) {
  MaterialDesc desc =
      Desc("coateddiffuse",
           {StringParam("string", "type", "coateddiffuse"), RGBParam("reflectance", 0.1, 0.2, 0.3),
            FloatParam("roughness", 0.25), FloatParam("thickness", 0.2), FloatParam("eta", 1.33),
            RGBParam("albedo", 0.5, 0.5, 0.5), FloatParam("g", 0.3)});
  desc.name = "Plastic";
  Material m = CreateMaterial(desc);
  EXPECT_EQ(m.name, "Plastic");
  EXPECT_EQ(m.reflectance, RGB(0.1f, 0.2f, 0.3f));
  EXPECT_FLOAT_EQ(m.alpha_x, 0.5f);
  EXPECT_FLOAT_EQ(m.alpha_y, 0.5f);
  EXPECT_FLOAT_EQ(m.thickness, 0.2f);
  EXPECT_FLOAT_EQ(m.eta.r, 1.33f);
  EXPECT_EQ(m.coat_albedo, RGB(0.5f));

  Material dielectric = CreateMaterial(Desc("dielectric", {RGBParam("eta", 1.7, 1.8, 1.9)}));
  EXPECT_FLOAT_EQ(dielectric.eta.r, 1.7f);
  EXPECT_FLOAT_EQ(dielectric.eta.b, 1.7f);  // no dispersion: one eta

  Material reflective = CreateMaterial(Desc("conductor", {RGBParam("reflectance", 0.9, 0.8, 0.7)}));
  EXPECT_TRUE(reflective.conductor_uses_reflectance);
  EXPECT_EQ(reflective.reflectance, RGB(0.9f, 0.8f, 0.7f));
}

TEST(CreateMaterial, RemapsRoughness) {
  Material remapped = CreateMaterial(Desc("conductor", {FloatParam("roughness", 0.04)}));
  EXPECT_FLOAT_EQ(remapped.alpha_x, 0.2f);
  EXPECT_FLOAT_EQ(remapped.alpha_y, 0.2f);
  EXPECT_FLOAT_EQ(RoughnessToAlpha(0.04f), 0.2f);

  Material raw = CreateMaterial(
      Desc("conductor", {FloatParam("uroughness", 0.04), FloatParam("vroughness", 0.09),
                         BoolParam("remaproughness", false)}));
  EXPECT_FLOAT_EQ(raw.alpha_x, 0.04f);
  EXPECT_FLOAT_EQ(raw.alpha_y, 0.09f);
  EXPECT_EQ(MaterialFlags(raw), uint32_t(kBxDFReflection | kBxDFGlossy));

  // u falls back to "roughness" when only vroughness is given
  Material mixed = CreateMaterial(
      Desc("dielectric", {FloatParam("roughness", 0.01), FloatParam("vroughness", 0.25)}));
  EXPECT_FLOAT_EQ(mixed.alpha_x, 0.1f);
  EXPECT_FLOAT_EQ(mixed.alpha_y, 0.5f);
}

TEST(CreateMaterial, RejectsUnsupportedInput) {
  EXPECT_NE(CreateError(Desc("diffuse", {StringParam("texture", "reflectance", "checks")}))
                .find("textures are not supported yet: reflectance"),
            std::string::npos);
  EXPECT_NE(CreateError(Desc("dielectric", {FloatParam("sigmaa", 1)}))
                .find("unused parameter \"float sigmaa\" in Material \"dielectric\""),
            std::string::npos);
  std::string unknown = CreateError(Desc("foo"));
  EXPECT_NE(unknown.find("unknown material type \"foo\""), std::string::npos) << unknown;
  EXPECT_EQ(unknown.rfind("scene.pbrt:12", 0), 0u) << unknown;
  EXPECT_NE(
      CreateError(Desc("diffuse", {StringParam("string", "normalmap", "n.png")})).find("normalmap"),
      std::string::npos);
  EXPECT_NE(CreateError(Desc("conductor", {FloatParam("displacement", 0.1)})).find("displacement"),
            std::string::npos);
  EXPECT_NE(CreateError(Desc("conductor",
                             {RGBParam("reflectance", 0.5, 0.5, 0.5), RGBParam("eta", 1, 1, 1)}))
                .find("reflectance"),
            std::string::npos);
  EXPECT_NE(CreateError(Desc("dielectric", {FloatParam("eta", 0)})).find("eta"), std::string::npos);
  EXPECT_NE(CreateError(Desc("conductor", {FloatParam("roughness", -0.1)})).find("roughness"),
            std::string::npos);
  EXPECT_NE(CreateError(Desc("mix")).find("not supported"), std::string::npos);
  // A parameter of another material type is unused here
  EXPECT_NE(CreateError(Desc("diffuse", {FloatParam("roughness", 0.1)})).find("roughness"),
            std::string::npos);
}

}  // namespace test_bsdf
}  // namespace lightfarm

namespace lightfarm {
namespace test_bsdf {

// bsdf.h contract used by camera paths: SampleBSDF picks the delta lobe exactly when
// uc < SpecularSamplingProbability.
TEST(BsdfContract, SpecularSamplingProbabilitySplitsSmoothCoatedDiffuse) {
  Material m;
  m.type = MaterialType::kCoatedDiffuse;
  m.reflectance = RGB(0.5f);
  m.eta = RGB(1.5f);
  for (float z : {0.9f, 0.5f, 0.1f, -0.7f}) {
    Vec3 wo = Normalize(Vec3(std::sqrt(1 - z * z), 0.1f, z));
    float p = SpecularSamplingProbability(m, wo);
    ASSERT_GT(p, 0.f);
    ASSERT_LT(p, 1.f);
    for (float uc : {0.f, p * 0.5f, p * 0.999f}) {
      auto s = SampleBSDF(m, wo, uc, {0.3f, 0.7f}, TransportMode::kRadiance);
      ASSERT_TRUE(s && s->IsSpecular()) << "uc " << uc << " p " << p;
    }
    for (float uc : {p, p + (1 - p) * 0.5f, 0.9999f}) {
      auto s = SampleBSDF(m, wo, uc, {0.3f, 0.7f}, TransportMode::kRadiance);
      ASSERT_TRUE(!s || !s->IsSpecular()) << "uc " << uc << " p " << p;
    }
  }
  Material diffuse;
  EXPECT_EQ(SpecularSamplingProbability(diffuse, {0, 0, 1}), 0.f);
  Material glass;
  glass.type = MaterialType::kDielectric;
  EXPECT_EQ(SpecularSamplingProbability(glass, {0, 0, 1}), 1.f);
}

}  // namespace test_bsdf
}  // namespace lightfarm
