// Materials of pbrt-v4 evaluated in the local shading frame. Each material is a handful of
// functions (Eval / Pdf / Sample) selected by a switch on Material::type; the math follows
// pbrt-v4's BxDFs (Ch. 9 and 14 of "Physically Based Rendering", 4th ed.) except for
// coateddiffuse, which pbrt evaluates stochastically and which is replaced here by a
// deterministic analytic layer model (see "Coated diffuse" below).
#include "common/scene/bsdf.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "common/scene/fresnel.h"
#include "common/scene/microfacet.h"
#include "common/scene/params.h"
#include "common/util/error.h"
#include "common/util/sampling.h"

namespace lightfarm {
namespace {

// Both directions strictly on the same side of the surface.
bool SameHemisphere(Vec3 a, Vec3 b) { return a.z * b.z > 0; }

bool IsSmooth(const Material& m) {
  return std::max(m.alpha_x, m.alpha_y) < kEffectivelySmoothAlpha;
}

// A glossy lobe the many-light split samples as a delta lobe (Material::sharp_alpha).
bool IsSharp(const Material& m) {
  return !IsSmooth(m) && std::max(m.alpha_x, m.alpha_y) < m.sharp_alpha;
}

// The flags of a sample from the material's microfacet lobe.
uint32_t MicrofacetLobe(const Material& m) { return IsSharp(m) ? kBxDFSpecular : kBxDFGlossy; }

// ---------------------------------------------------------------------------------------
// Diffuse (Lambertian, two-sided)

RGB EvalDiffuse(const Material& m, Vec3 wo, Vec3 wi) {
  if (!SameHemisphere(wo, wi)) return RGB(0.f);
  return m.reflectance * kInvPi;
}

float PdfDiffuse(Vec3 wo, Vec3 wi) {
  if (!SameHemisphere(wo, wi)) return 0.f;
  return CosineHemispherePdf(std::abs(wi.z));
}

std::optional<BSDFSample> SampleDiffuse(const Material& m, Vec3 wo, Vec2 u) {
  if (wo.z == 0) return std::nullopt;
  Vec3 wi = SampleCosineHemisphere(u);
  if (wi.z == 0) return std::nullopt;
  if (wo.z < 0) wi.z = -wi.z;
  BSDFSample s;
  s.f = m.reflectance * kInvPi;
  s.wi = wi;
  s.pdf = CosineHemispherePdf(std::abs(wi.z));
  s.flags = kBxDFReflection | kBxDFDiffuse;
  return s;
}

// ---------------------------------------------------------------------------------------
// Conductor (two-sided): perfect mirror or Trowbridge-Reitz microfacets, complex Fresnel.

// Fresnel reflectance of the conductor. Given "reflectance" instead of eta / k, pbrt-v4's
// mapping is used: eta = 1 and k = 2 sqrt(r / (1 - r)), the conductor whose normal-incidence
// reflectance k^2 / (4 + k^2) is exactly r; the complex Fresnel equations then brighten it
// towards grazing angles much like Schlick's approximation with F0 = r.
RGB ConductorFresnel(const Material& m, float cos_i) {
  if (!m.conductor_uses_reflectance) return FrComplex(cos_i, m.eta, m.k);
  RGB f;
  for (int c = 0; c < 3; ++c) {
    float r = Clamp(m.reflectance[c], 0.f, 0.9999f);
    f[c] = FrComplex(cos_i, 1.f, 2 * std::sqrt(r / (1 - r)));
  }
  return f;
}

// The microfacet lobe itself, sharp or not.
RGB ConductorLobe(const Material& m, Vec3 wo, Vec3 wi) {
  if (IsSmooth(m) || !SameHemisphere(wo, wi)) return RGB(0.f);
  // Work in the hemisphere of wo
  if (wo.z < 0) {
    wo = -wo;
    wi = -wi;
  }
  Vec3 wm = wo + wi;
  if (LengthSquared(wm) == 0) return RGB(0.f);
  wm = Normalize(wm);
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  // Torrance-Sparrow: D F G / (4 cos_o cos_i)
  float dg = distrib.D(wm) * distrib.G(wo, wi) / (4 * wo.z * wi.z);
  if (!std::isfinite(dg)) return RGB(0.f);
  return ConductorFresnel(m, AbsDot(wo, wm)) * dg;
}

float ConductorLobePdf(const Material& m, Vec3 wo, Vec3 wi) {
  if (IsSmooth(m) || !SameHemisphere(wo, wi)) return 0.f;
  if (wo.z < 0) {
    wo = -wo;
    wi = -wi;
  }
  Vec3 wm = wo + wi;
  if (LengthSquared(wm) == 0) return 0.f;
  wm = Normalize(wm);
  // Visible-normal density times the Jacobian of reflection, 1 / (4 |wo.wm|)
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  float pdf = distrib.VisibleD(wo, wm) / (4 * AbsDot(wo, wm));
  return std::isfinite(pdf) ? pdf : 0.f;
}

RGB EvalConductor(const Material& m, Vec3 wo, Vec3 wi) {
  return IsSharp(m) ? RGB(0.f) : ConductorLobe(m, wo, wi);
}
float PdfConductor(const Material& m, Vec3 wo, Vec3 wi) { return IsSharp(m) ? 0.f : ConductorLobePdf(m, wo, wi); }

std::optional<BSDFSample> SampleConductor(const Material& m, Vec3 wo, Vec2 u) {
  if (wo.z == 0) return std::nullopt;
  float side = wo.z < 0 ? -1.f : 1.f;
  Vec3 wo_up = wo * side;
  BSDFSample s;
  if (IsSmooth(m)) {
    // Perfect specular reflection
    Vec3 wi(-wo_up.x, -wo_up.y, wo_up.z);
    s.f = ConductorFresnel(m, wi.z) / wi.z;
    s.wi = wi * side;
    s.pdf = 1;
    s.flags = kBxDFReflection | kBxDFSpecular;
    return s;
  }
  // Sample a visible microfacet normal and reflect about it
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  Vec3 wm = distrib.SampleVisibleNormal(wo_up, u);
  Vec3 wi = Reflect(wo_up, wm);
  if (wi.z <= 0) return std::nullopt;
  s.wi = wi * side;
  s.f = ConductorLobe(m, wo, s.wi);
  s.pdf = ConductorLobePdf(m, wo, s.wi);
  if (s.pdf == 0) return std::nullopt;
  s.flags = kBxDFReflection | MicrofacetLobe(m);
  return s;
}

// ---------------------------------------------------------------------------------------
// Dielectric: specular or rough (Walter et al. 2007) reflection and transmission. eta = 1 is
// an index-matched boundary: light passes straight through whatever the roughness.

bool DielectricIsPassThrough(const Material& m) { return m.eta.r == 1.f; }

// The generalised half vector of (wo, wi) facing +z, with the relative IOR etap crossed.
// False when the configuration is degenerate or uses a back-facing microfacet.
bool DielectricHalfVector(float eta, Vec3 wo, Vec3 wi, Vec3* wm, float* etap) {
  float cos_o = wo.z, cos_i = wi.z;
  if (cos_o == 0 || cos_i == 0) return false;
  bool reflect = cos_i * cos_o > 0;
  *etap = reflect ? 1.f : (cos_o > 0 ? eta : 1 / eta);
  Vec3 h = wi * *etap + wo;
  if (LengthSquared(h) == 0) return false;
  h = FaceForward(Normalize(h), Vec3(0, 0, 1));
  // Microfacets seen from behind by either direction contribute nothing
  if (Dot(h, wi) * cos_i < 0 || Dot(h, wo) * cos_o < 0) return false;
  *wm = h;
  return true;
}

RGB DielectricLobe(const Material& m, Vec3 wo, Vec3 wi, TransportMode mode) {
  float eta = m.eta.r;
  if (DielectricIsPassThrough(m) || IsSmooth(m)) return RGB(0.f);
  Vec3 wm;
  float etap;
  if (!DielectricHalfVector(eta, wo, wi, &wm, &etap)) return RGB(0.f);
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  float fr = FrDielectric(Dot(wo, wm), eta);
  float f;
  if (SameHemisphere(wo, wi)) {
    f = distrib.D(wm) * distrib.G(wo, wi) * fr / std::abs(4 * wi.z * wo.z);
  } else {
    // Walter et al. 2007, Eq. 21
    float denom = Sqr(Dot(wi, wm) + Dot(wo, wm) / etap) * wi.z * wo.z;
    if (denom == 0) return RGB(0.f);
    f = distrib.D(wm) * (1 - fr) * distrib.G(wo, wi) * std::abs(Dot(wi, wm) * Dot(wo, wm) / denom);
    // Radiance is compressed into the denser medium (pbrt-v4 Sec. 9.5.2)
    if (mode == TransportMode::kRadiance) f /= Sqr(etap);
  }
  return std::isfinite(f) ? RGB(f) : RGB(0.f);
}

float DielectricLobePdf(const Material& m, Vec3 wo, Vec3 wi) {
  float eta = m.eta.r;
  if (DielectricIsPassThrough(m) || IsSmooth(m)) return 0.f;
  Vec3 wm;
  float etap;
  if (!DielectricHalfVector(eta, wo, wi, &wm, &etap)) return 0.f;
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  // The lobe is chosen with probability R (reflection) or T = 1 - R (transmission)
  float r = FrDielectric(Dot(wo, wm), eta);
  float pdf;
  if (SameHemisphere(wo, wi)) {
    pdf = distrib.VisibleD(wo, wm) / (4 * AbsDot(wo, wm)) * r;
  } else {
    float dwm_dwi = AbsDot(wi, wm) / Sqr(Dot(wi, wm) + Dot(wo, wm) / etap);
    pdf = distrib.VisibleD(wo, wm) * dwm_dwi * (1 - r);
  }
  return std::isfinite(pdf) ? pdf : 0.f;
}

RGB EvalDielectric(const Material& m, Vec3 wo, Vec3 wi, TransportMode mode) {
  return IsSharp(m) ? RGB(0.f) : DielectricLobe(m, wo, wi, mode);
}
float PdfDielectric(const Material& m, Vec3 wo, Vec3 wi) { return IsSharp(m) ? 0.f : DielectricLobePdf(m, wo, wi); }

std::optional<BSDFSample> SampleDielectric(const Material& m, Vec3 wo, float uc, Vec2 u,
                                           TransportMode mode) {
  if (wo.z == 0) return std::nullopt;
  float eta = m.eta.r;
  BSDFSample s;
  if (DielectricIsPassThrough(m) || IsSmooth(m)) {
    // Specular: choose reflection with probability R, else refraction
    float r = DielectricIsPassThrough(m) ? 0.f : FrDielectric(wo.z, eta);
    if (uc < r) {
      s.wi = Vec3(-wo.x, -wo.y, wo.z);
      s.f = RGB(r / std::abs(s.wi.z));
      s.pdf = r;
      s.flags = kBxDFReflection | kBxDFSpecular;
      return s;
    }
    float etap = 1;
    Vec3 wi = -wo;  // index-matched: straight through
    if (!DielectricIsPassThrough(m) && (!Refract(wo, Vec3(0, 0, 1), eta, &etap, &wi) || wi.z == 0))
      return std::nullopt;
    float ft = (1 - r) / std::abs(wi.z);
    if (mode == TransportMode::kRadiance) ft /= Sqr(etap);
    s.wi = wi;
    s.f = RGB(ft);
    s.pdf = 1 - r;
    s.flags = kBxDFTransmission | kBxDFSpecular;
    s.eta = etap;
    return s;
  }
  // Rough: sample a visible microfacet normal, then reflect or refract about it
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  Vec3 wm = distrib.SampleVisibleNormal(wo, u);
  float r = FrDielectric(Dot(wo, wm), eta);
  Vec3 wi;
  float etap = 1;
  if (uc < r) {
    wi = Reflect(wo, wm);
    if (!SameHemisphere(wo, wi)) return std::nullopt;
    s.flags = kBxDFReflection | MicrofacetLobe(m);
  } else {
    if (!Refract(wo, wm, eta, &etap, &wi) || wi.z == 0 || SameHemisphere(wo, wi))
      return std::nullopt;
    s.flags = kBxDFTransmission | MicrofacetLobe(m);
    s.eta = etap;
  }
  // f and pdf from the same expressions Eval/Pdf use, so MIS weights agree exactly
  s.wi = wi;
  s.f = DielectricLobe(m, wo, wi, mode);
  s.pdf = DielectricLobePdf(m, wo, wi);
  if (s.pdf == 0) return std::nullopt;
  return s;
}

// ---------------------------------------------------------------------------------------
// Thin dielectric: a slab with two parallel specular interfaces. Inter-reflections inside the
// slab add up to R' = R + T^2 R / (1 - R^2), T' = 1 - R'; the transmitted ray is not bent.

std::optional<BSDFSample> SampleThinDielectric(const Material& m, Vec3 wo, float uc) {
  if (wo.z == 0) return std::nullopt;
  float r = FrDielectric(std::abs(wo.z), m.eta.r);
  float t = 1 - r;
  if (r < 1) {
    r += Sqr(t) * r / (1 - Sqr(r));
    t = 1 - r;
  }
  BSDFSample s;
  if (uc < r) {
    s.wi = Vec3(-wo.x, -wo.y, wo.z);
    s.f = RGB(r / std::abs(wo.z));
    s.pdf = r;
    s.flags = kBxDFReflection | kBxDFSpecular;
  } else {
    s.wi = -wo;
    s.f = RGB(t / std::abs(wo.z));
    s.pdf = t;
    s.flags = kBxDFTransmission | kBxDFSpecular;
  }
  return s;
}

// ---------------------------------------------------------------------------------------
// Diffuse transmission: Lambertian reflection R/pi on the side of wo, T/pi on the other side.

RGB EvalDiffuseTransmission(const Material& m, Vec3 wo, Vec3 wi) {
  if (wo.z == 0 || wi.z == 0) return RGB(0.f);
  return (SameHemisphere(wo, wi) ? m.reflectance : m.transmittance) * kInvPi;
}

// Probability of sampling the reflection lobe.
float DiffuseReflectionProbability(const Material& m) {
  float pr = m.reflectance.Max(), pt = m.transmittance.Max();
  if (pr + pt <= 0) return 1.f;
  return pr / (pr + pt);
}

float PdfDiffuseTransmission(const Material& m, Vec3 wo, Vec3 wi) {
  if (wo.z == 0 || wi.z == 0) return 0.f;
  float pr = DiffuseReflectionProbability(m);
  return CosineHemispherePdf(std::abs(wi.z)) * (SameHemisphere(wo, wi) ? pr : 1 - pr);
}

std::optional<BSDFSample> SampleDiffuseTransmission(const Material& m, Vec3 wo, float uc, Vec2 u) {
  if (wo.z == 0) return std::nullopt;
  float pr = DiffuseReflectionProbability(m);
  Vec3 wi = SampleCosineHemisphere(u);
  if (wi.z == 0) return std::nullopt;
  bool reflect = uc < pr;
  // Put wi on the side of wo for reflection, on the other side for transmission
  if ((wo.z < 0) == reflect) wi.z = -wi.z;
  BSDFSample s;
  s.wi = wi;
  s.f = EvalDiffuseTransmission(m, wo, wi);
  s.pdf = CosineHemispherePdf(std::abs(wi.z)) * (reflect ? pr : 1 - pr);
  if (s.pdf == 0) return std::nullopt;
  s.flags = kBxDFDiffuse | (reflect ? kBxDFReflection : kBxDFTransmission);
  return s;
}

// ---------------------------------------------------------------------------------------
// Coated diffuse (two-sided).
//
// pbrt-v4's CoatedDiffuseMaterial is a LayeredBxDF evaluated by a stochastic random walk
// between the coat and the base; the lighting matrix needs a deterministic f(wo, wi), so we
// use the analytic layer model of Weidlich & Wilkie 2007 / Mitsuba's "plastic" and
// "roughplastic" instead:
//
//   f = f_coat(wo, wi)
//     + (1 - E(cos_o)) (1 - E(cos_i)) R A(wo, wi) / (pi eta^2 (1 - R F_dr,int))
//
// - f_coat: reflection off the dielectric coat of relative IOR eta: a mirror delta of weight
//   F(cos_o) when the coat is smooth, else the Trowbridge-Reitz microfacet reflection
//   D G F(wo.wm) / (4 cos_o cos_i) (no transmission lobe: the base is opaque).
// - E is the fraction of light the coat reflects: the Fresnel reflectance F for a smooth coat;
//   for a rough coat the directional albedo of f_coat, tabulated over the direction once
//   per (alpha_x, alpha_y, eta), as roughplastic's precomputed rough transmittance.
//   Everything the coat does not reflect is taken to reach the base, including the energy
//   single-scattering microfacet models lose to masking (pbrt's random walk would reflect it
//   off the coat again).
// - The base of albedo R is Lambertian: light enters with (1 - E(cos_i)), bounces between
//   base and coat (internal diffuse reflectance F_dr,int: the geometric series
//   1 / (1 - R F_dr,int)), leaves with (1 - E(cos_o)) and its radiance is divided by eta^2 on
//   exit. F_dr,int follows from eta^2 (1 - F_dr,int) = 1 - F_dr,ext (reciprocity of the
//   interface), with F_dr,ext the cosine-weighted hemispherical average of E; so with R = 1
//   and no absorption the material reflects all the light, for smooth and rough coats alike.
// - A(wo, wi) = exp(-thickness (1 - albedo) (1/cos_o' + 1/cos_i')) is the attenuation of the
//   layer's medium along the directions refracted at the macro normal (cos' = cosines inside
//   the coat), as pbrt's Tr(thickness, w). pbrt's medium scatters with "albedo" and a
//   Henyey-Greenstein "g"; here only its absorbed fraction (1 - albedo) attenuates and the
//   scattered light is assumed to reach the base anyway (exact for albedo = 0, the default;
//   "g" is ignored). The attenuation of the internally reflected light is neglected.

float CoatEta(const Material& m) { return m.eta.r > 0 ? m.eta.r : 1.f; }

// E of a rough coat is tabulated at cosines mu_i = t_i^2, t_i = i / (N - 1) (denser at
// grazing angles, where E changes fastest) and, for anisotropic roughness, at azimuths
// phi_j = j / (M - 1) * pi / 2 (a quarter turn covers all of them by symmetry).
constexpr int kCoatCosines = 32;
constexpr int kCoatAzimuths = 8;
float CoatTableCos(int i) {
  float t = static_cast<float>(i) / (kCoatCosines - 1);
  return std::max(t * t, 1e-4f);
}

struct CoatTable {
  float alpha_x = 0, alpha_y = 0, eta = 1;  // the key (alphas 0 for every smooth coat)
  int azimuths = 1;                         // 1 for isotropic roughness
  std::array<float, kCoatCosines * kCoatAzimuths> albedo{};  // rough: E[cos][azimuth]
  float internal_fdr = 0;                                    // F_dr,int
};

// Directional albedo of the rough coat's reflection lobe for wo, the integral of
// f_coat cos over wi, by a deterministic midpoint rule on visible-normal samples (weight
// F G / G1).
float RoughCoatAlbedo(const TrowbridgeReitz& distrib, float eta, Vec3 wo) {
  constexpr int kGrid = 32;
  float g1 = distrib.G1(wo);
  double sum = 0;
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      Vec2 u((i + 0.5f) / kGrid, (j + 0.5f) / kGrid);
      Vec3 wm = distrib.SampleVisibleNormal(wo, u);
      Vec3 wi = Reflect(wo, wm);
      if (wi.z <= 0) continue;
      sum += static_cast<double>(FrDielectric(Dot(wo, wm), eta) * distrib.G(wo, wi) / g1);
    }
  }
  return static_cast<float>(sum / (kGrid * kGrid));
}

// Hemispherical (cosine-weighted) average of the Fresnel reflectance for light arriving from
// outside: F_dr,ext = int_0^1 2 mu F(mu) dmu, by composite Simpson on a smooth integrand.
float SmoothExternalDiffuseFresnel(float eta) {
  constexpr int kIntervals = 128;
  float h = 1.f / kIntervals;
  float sum = 0;
  for (int i = 0; i <= kIntervals; ++i) {
    float mu = i * h;
    float w = (i == 0 || i == kIntervals) ? 1.f : (i % 2 == 1 ? 4.f : 2.f);
    sum += w * 2 * mu * FrDielectric(mu, eta);
  }
  return sum * h / 3;
}

CoatTable BuildCoatTable(float alpha_x, float alpha_y, float eta) {
  CoatTable table;
  table.alpha_x = alpha_x;
  table.alpha_y = alpha_y;
  table.eta = eta;
  float fdr_ext;
  if (std::max(alpha_x, alpha_y) < kEffectivelySmoothAlpha) {
    fdr_ext = SmoothExternalDiffuseFresnel(eta);
  } else {
    TrowbridgeReitz distrib(alpha_x, alpha_y);
    table.azimuths = alpha_x == alpha_y ? 1 : kCoatAzimuths;
    std::array<float, kCoatCosines> mean_over_azimuth{};
    for (int i = 0; i < kCoatCosines; ++i) {
      float cos_o = CoatTableCos(i), sin_o = SafeSqrt(1 - Sqr(cos_o));
      float weight_sum = 0;
      for (int j = 0; j < table.azimuths; ++j) {
        float phi = table.azimuths == 1 ? 0.f : (kPi / 2) * j / (table.azimuths - 1);
        Vec3 wo(sin_o * std::cos(phi), sin_o * std::sin(phi), cos_o);
        float e = RoughCoatAlbedo(distrib, eta, wo);
        table.albedo[i * kCoatAzimuths + j] = e;
        // Trapezoids over the quarter turn
        float w = (table.azimuths > 1 && (j == 0 || j == table.azimuths - 1)) ? 0.5f : 1.f;
        mean_over_azimuth[i] += w * e;
        weight_sum += w;
      }
      mean_over_azimuth[i] /= weight_sum;
    }
    // F_dr,ext = int_0^1 2 mu E(mu) dmu, trapezoids between the nodes
    fdr_ext = 0;
    for (int i = 0; i + 1 < kCoatCosines; ++i) {
      float mu0 = CoatTableCos(i), mu1 = CoatTableCos(i + 1);
      fdr_ext += (mu1 - mu0) * (mu0 * mean_over_azimuth[i] + mu1 * mean_over_azimuth[i + 1]);
    }
  }
  // eta^2 (1 - F_dr,int) = 1 - F_dr,ext: avoids integrating the internal side, whose
  // integrand has a kink at the critical angle
  table.internal_fdr = Clamp(1 - (1 - fdr_ext) / Sqr(eta), 0.f, 1.f);
  return table;
}

// The table of a coat, built on first use by each thread (~2 ms for a rough coat, ~15 ms if
// anisotropic; scenes have a handful of coats). Deterministic, so every thread and worker
// gets the same values.
const CoatTable& GetCoatTable(const Material& m) {
  constexpr size_t kMaxCachedCoats = 64;
  thread_local std::vector<CoatTable> cache;
  bool smooth = IsSmooth(m);
  float ax = smooth ? 0.f : m.alpha_x, ay = smooth ? 0.f : m.alpha_y, eta = CoatEta(m);
  for (const CoatTable& t : cache)
    if (t.alpha_x == ax && t.alpha_y == ay && t.eta == eta) return t;
  if (cache.size() == kMaxCachedCoats) cache.erase(cache.begin());
  cache.push_back(BuildCoatTable(ax, ay, eta));
  return cache.back();
}

// E(w): the fraction of light arriving from w (w.z > 0) that the coat reflects.
float CoatReflectance(const Material& m, const CoatTable& table, Vec3 w) {
  if (IsSmooth(m)) return FrDielectric(w.z, CoatEta(m));
  float s = std::sqrt(Clamp(w.z, 0.f, 1.f)) * (kCoatCosines - 1);
  int i = std::min(static_cast<int>(s), kCoatCosines - 2);
  float fi = s - i;
  const float* e = &table.albedo[0];
  if (table.azimuths == 1) return Lerp(fi, e[i * kCoatAzimuths], e[(i + 1) * kCoatAzimuths]);
  // Bilinear in (sqrt(cos), azimuth folded into the first quadrant)
  float t = std::atan2(std::abs(w.y), std::abs(w.x)) * (2 / kPi) * (kCoatAzimuths - 1);
  int j = std::min(static_cast<int>(t), kCoatAzimuths - 2);
  float fj = t - j;
  auto at = [&](int ci, int aj) { return e[ci * kCoatAzimuths + aj]; };
  return Lerp(fi, Lerp(fj, at(i, j), at(i, j + 1)), Lerp(fj, at(i + 1, j), at(i + 1, j + 1)));
}

// The diffuse base seen through the coat, for wo.z, wi.z > 0.
RGB EvalCoatedBase(const Material& m, Vec3 wo, Vec3 wi) {
  float eta = CoatEta(m);
  const CoatTable& table = GetCoatTable(m);
  float eo = CoatReflectance(m, table, wo), ei = CoatReflectance(m, table, wi);
  // Cosines of the refracted directions inside the coat
  float cos_o_in = SafeSqrt(1 - (1 - Sqr(wo.z)) / Sqr(eta));
  float cos_i_in = SafeSqrt(1 - (1 - Sqr(wi.z)) / Sqr(eta));
  if (cos_o_in == 0 || cos_i_in == 0 || eo >= 1 || ei >= 1) return RGB(0.f);
  float path = 1 / cos_o_in + 1 / cos_i_in;
  float common = (1 - eo) * (1 - ei) / (kPi * Sqr(eta));
  RGB f;
  for (int c = 0; c < 3; ++c) {
    float r = Clamp(m.reflectance[c], 0.f, 1.f);
    float absorption = m.thickness * std::max(0.f, 1 - m.coat_albedo[c]);
    f[c] = common * r * std::exp(-absorption * path) / (1 - r * table.internal_fdr);
  }
  return f;
}

// Probability of sampling the coat rather than the base: proportional to the energy each
// sends back (E(wo) vs. what is transmitted to the base), kept away from 0 and 1 so
// neither lobe is starved.
float CoatSamplingProbability(const Material& m, Vec3 wo) {
  float ws = IsSmooth(m) ? FrDielectric(wo.z, CoatEta(m)) : CoatReflectance(m, GetCoatTable(m), wo);
  float wd = (1 - ws) * Clamp(m.reflectance.Average(), 0.f, 1.f);
  if (ws <= 0) return 0.f;
  if (wd <= 0) return 1.f;
  return Clamp(ws / (ws + wd), 0.05f, 0.95f);
}

// Rough coat reflection (Torrance-Sparrow with dielectric Fresnel), both cosines > 0.
float EvalCoatGlossy(const Material& m, Vec3 wo, Vec3 wi) {
  Vec3 wm = wo + wi;
  if (LengthSquared(wm) == 0) return 0.f;
  wm = Normalize(wm);
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  float f =
      distrib.D(wm) * distrib.G(wo, wi) * FrDielectric(Dot(wo, wm), CoatEta(m)) / (4 * wo.z * wi.z);
  return std::isfinite(f) ? f : 0.f;
}

float PdfCoatGlossy(const Material& m, Vec3 wo, Vec3 wi) {
  Vec3 wm = wo + wi;
  if (LengthSquared(wm) == 0) return 0.f;
  wm = Normalize(wm);
  TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
  float pdf = distrib.VisibleD(wo, wm) / (4 * AbsDot(wo, wm));
  return std::isfinite(pdf) ? pdf : 0.f;
}

RGB EvalCoatedDiffuse(const Material& m, Vec3 wo, Vec3 wi) {
  if (!SameHemisphere(wo, wi)) return RGB(0.f);
  if (wo.z < 0) {
    wo = -wo;
    wi = -wi;
  }
  RGB f = EvalCoatedBase(m, wo, wi);
  if (!ActsAsDelta(m)) f += RGB(EvalCoatGlossy(m, wo, wi));
  return f;
}

float PdfCoatedDiffuse(const Material& m, Vec3 wo, Vec3 wi) {
  if (!SameHemisphere(wo, wi)) return 0.f;
  if (wo.z < 0) {
    wo = -wo;
    wi = -wi;
  }
  float p_coat = CoatSamplingProbability(m, wo);
  float pdf = (1 - p_coat) * CosineHemispherePdf(wi.z);
  if (!ActsAsDelta(m)) pdf += p_coat * PdfCoatGlossy(m, wo, wi);
  return pdf;
}

std::optional<BSDFSample> SampleCoatedDiffuse(const Material& m, Vec3 wo, float uc, Vec2 u) {
  if (wo.z == 0) return std::nullopt;
  float side = wo.z < 0 ? -1.f : 1.f;
  Vec3 wo_up = wo * side;
  float p_coat = CoatSamplingProbability(m, wo_up);
  BSDFSample s;
  if (uc < p_coat && IsSmooth(m)) {
    // Mirror reflection off the smooth coat
    Vec3 wi(-wo_up.x, -wo_up.y, wo_up.z);
    s.f = RGB(FrDielectric(wo_up.z, CoatEta(m)) / wi.z);
    s.wi = wi * side;
    s.pdf = p_coat;
    s.flags = kBxDFReflection | kBxDFSpecular;
    return s;
  }
  Vec3 wi;
  if (uc < p_coat) {
    TrowbridgeReitz distrib(m.alpha_x, m.alpha_y);
    wi = Reflect(wo_up, distrib.SampleVisibleNormal(wo_up, u));
    s.flags = kBxDFReflection | MicrofacetLobe(m);
    if (IsSharp(m)) {
      // The sharp coat alone, chosen with probability p_coat (the base is the rows' part).
      if (wi.z <= 0) return std::nullopt;
      s.wi = wi * side;
      s.f = RGB(EvalCoatGlossy(m, wo_up, wi));
      s.pdf = p_coat * PdfCoatGlossy(m, wo_up, wi);
      if (s.pdf == 0) return std::nullopt;
      return s;
    }
  } else {
    wi = SampleCosineHemisphere(u);
    s.flags = kBxDFReflection | kBxDFDiffuse;
  }
  if (wi.z <= 0) return std::nullopt;
  s.wi = wi * side;
  if (ActsAsDelta(m)) {
    // Only the base is non-delta: f and pdf of the diffuse lobe alone
    s.f = EvalCoatedBase(m, wo_up, wi);
    s.pdf = (1 - p_coat) * CosineHemispherePdf(wi.z);
  } else {
    s.f = EvalCoatedDiffuse(m, wo, s.wi);
    s.pdf = PdfCoatedDiffuse(m, wo, s.wi);
  }
  if (s.pdf == 0) return std::nullopt;
  return s;
}

// ---------------------------------------------------------------------------------------
// CreateMaterial helpers

FileLoc ParamLoc(const MaterialDesc& desc, const std::string& name) {
  const Param* p = desc.params.Find(name);
  return (p && !p->loc.file.empty()) ? p->loc : desc.loc;
}

// Features of pbrt-v4 materials that lightfarm does not implement are errors, never skipped.
void RejectUnsupportedParams(const MaterialDesc& desc) {
  // pbrt-v4 treats an empty file name as "no normal map"
  if (!desc.params.GetOneString("normalmap", "").empty())
    throw SceneError(ParamLoc(desc, "normalmap"), "normal maps are not supported yet: normalmap");
  if (desc.params.Has("displacement"))
    throw SceneError(ParamLoc(desc, "displacement"),
                     "displacement is not supported yet: displacement");
  for (const Param& p : desc.params.params()) {
    if (p.type == "texture")
      throw SceneError(ParamLoc(desc, p.name), "textures are not supported yet: " + p.name);
  }
}

// eta of a dielectric interface: a single positive float (the red channel of a spectrum;
// lightfarm renders in RGB and has no dispersion).
float GetInterfaceEta(const MaterialDesc& desc) {
  std::optional<RGB> eta = desc.params.GetOneRGB("eta", SpectrumType::kUnbounded);
  float value = eta ? eta->r : 1.5f;
  if (!(value > 0) || !std::isfinite(value))
    throw SceneError(ParamLoc(desc, "eta"),
                     "\"eta\" must be positive, got " + std::to_string(value));
  return value;
}

RGB GetAlbedo(const MaterialDesc& desc, const std::string& name, float def) {
  return desc.params.GetOneRGB(name, SpectrumType::kAlbedo).value_or(RGB(def));
}

// uroughness / vroughness (each defaulting to "roughness", itself 0) and remaproughness.
void ReadRoughness(const MaterialDesc& desc, Material* m) {
  const ParamSet& params = desc.params;
  auto read = [&](const char* name) {
    const char* used = params.Has(name) ? name : "roughness";
    float r = params.GetOneFloat(used, 0.f);
    if (!(r >= 0) || !std::isfinite(r))
      throw SceneError(ParamLoc(desc, used),
                       std::string("\"") + used + "\" must be >= 0, got " + std::to_string(r));
    return r;
  };
  float u = read("uroughness"), v = read("vroughness");
  bool remap = params.GetOneBool("remaproughness", true);
  m->alpha_x = remap ? RoughnessToAlpha(u) : u;
  m->alpha_y = remap ? RoughnessToAlpha(v) : v;
}

}  // namespace

float RoughnessToAlpha(float roughness) { return std::sqrt(std::max(0.f, roughness)); }

bool ActsAsDelta(const Material& m) { return IsSmooth(m) || IsSharp(m); }

namespace {
bool HasMicrofacetLobe(const Material& m) {
  return m.type == MaterialType::kConductor || m.type == MaterialType::kCoatedDiffuse ||
         (m.type == MaterialType::kDielectric && !DielectricIsPassThrough(m));
}
}  // namespace

bool HasSharpLobe(const Material& m) { return HasMicrofacetLobe(m) && IsSharp(m); }

bool HasRoughMicrofacetLobe(const Material& m) { return HasMicrofacetLobe(m) && !IsSmooth(m) && !IsSharp(m); }

RGB EvalSharpLobe(const Material& m, Vec3 wo, Vec3 wi, TransportMode mode) {
  if (!HasSharpLobe(m) || wo.z == 0 || wi.z == 0) return RGB(0.f);
  switch (m.type) {
    case MaterialType::kConductor:
      return ConductorLobe(m, wo, wi);
    case MaterialType::kDielectric:
      return DielectricLobe(m, wo, wi, mode);
    case MaterialType::kCoatedDiffuse:
      if (!SameHemisphere(wo, wi)) return RGB(0.f);
      return wo.z < 0 ? RGB(EvalCoatGlossy(m, -wo, -wi)) : RGB(EvalCoatGlossy(m, wo, wi));
    default:
      return RGB(0.f);
  }
}

float PdfSharpLobe(const Material& m, Vec3 wo, Vec3 wi) {
  if (!HasSharpLobe(m) || wo.z == 0 || wi.z == 0) return 0.f;
  switch (m.type) {
    case MaterialType::kConductor:
      return ConductorLobePdf(m, wo, wi);
    case MaterialType::kDielectric:
      return DielectricLobePdf(m, wo, wi);
    case MaterialType::kCoatedDiffuse: {
      if (!SameHemisphere(wo, wi)) return 0.f;
      if (wo.z < 0) {
        wo = -wo;
        wi = -wi;
      }
      return CoatSamplingProbability(m, wo) * PdfCoatGlossy(m, wo, wi);
    }
    default:
      return 0.f;
  }
}

uint32_t MaterialFlags(const Material& m) {
  uint32_t rough = ActsAsDelta(m) ? kBxDFSpecular : kBxDFGlossy;
  switch (m.type) {
    case MaterialType::kDiffuse:
      // Also for black reflectance: the surface is still opaque (flags 0 means "pass through")
      return kBxDFReflection | kBxDFDiffuse;
    case MaterialType::kCoatedDiffuse:
      return kBxDFReflection | kBxDFDiffuse | rough;
    case MaterialType::kConductor:
      return kBxDFReflection | rough;
    case MaterialType::kDielectric:
      if (DielectricIsPassThrough(m)) return kBxDFTransmission | kBxDFSpecular;
      return kBxDFReflection | kBxDFTransmission | rough;
    case MaterialType::kThinDielectric:
      return kBxDFReflection | kBxDFTransmission | kBxDFSpecular;
    case MaterialType::kDiffuseTransmission: {
      uint32_t flags = kBxDFDiffuse;
      if (!m.reflectance.IsBlack() || m.transmittance.IsBlack()) flags |= kBxDFReflection;
      if (!m.transmittance.IsBlack()) flags |= kBxDFTransmission;
      return flags;
    }
    case MaterialType::kInterface:
      return kBxDFUnset;
  }
  return kBxDFUnset;
}

RGB EvalBSDF(const Material& m, Vec3 wo, Vec3 wi, TransportMode mode) {
  if (wo.z == 0 || wi.z == 0) return RGB(0.f);
  switch (m.type) {
    case MaterialType::kDiffuse:
      return EvalDiffuse(m, wo, wi);
    case MaterialType::kCoatedDiffuse:
      return EvalCoatedDiffuse(m, wo, wi);
    case MaterialType::kConductor:
      return EvalConductor(m, wo, wi);
    case MaterialType::kDielectric:
      return EvalDielectric(m, wo, wi, mode);
    case MaterialType::kDiffuseTransmission:
      return EvalDiffuseTransmission(m, wo, wi);
    case MaterialType::kThinDielectric:
    case MaterialType::kInterface:
      return RGB(0.f);
  }
  return RGB(0.f);
}

// The sampling densities do not depend on the transport mode (only f does).
float PdfBSDF(const Material& m, Vec3 wo, Vec3 wi, TransportMode /*mode*/) {
  if (wo.z == 0 || wi.z == 0) return 0.f;
  switch (m.type) {
    case MaterialType::kDiffuse:
      return PdfDiffuse(wo, wi);
    case MaterialType::kCoatedDiffuse:
      return PdfCoatedDiffuse(m, wo, wi);
    case MaterialType::kConductor:
      return PdfConductor(m, wo, wi);
    case MaterialType::kDielectric:
      return PdfDielectric(m, wo, wi);
    case MaterialType::kDiffuseTransmission:
      return PdfDiffuseTransmission(m, wo, wi);
    case MaterialType::kThinDielectric:
    case MaterialType::kInterface:
      return 0.f;
  }
  return 0.f;
}

float SpecularSamplingProbability(const Material& m, Vec3 wo) {
  uint32_t flags = MaterialFlags(m);
  if (!(flags & kBxDFSpecular)) return 0.f;
  if (IsPurelySpecular(flags)) return 1.f;
  if (m.type == MaterialType::kCoatedDiffuse) {
    // SampleCoatedDiffuse works on the upper hemisphere (the material is two-sided).
    Vec3 wo_up = wo.z < 0 ? -wo : wo;
    return CoatSamplingProbability(m, wo_up);
  }
  return 0.f;
}

float DeltaReflectionProbability(const Material& m, Vec3 wo) {
  if (m.type != MaterialType::kDielectric || DielectricIsPassThrough(m) || !IsSmooth(m) || wo.z == 0) return -1.f;
  const float r = FrDielectric(wo.z, m.eta.r);  // the same expression SampleDielectric uses
  return r > 0.f && r < 1.f ? r : -1.f;
}

std::optional<BSDFSample> SampleBSDF(const Material& m, Vec3 wo, float uc, Vec2 u,
                                     TransportMode mode) {
  std::optional<BSDFSample> s;
  switch (m.type) {
    case MaterialType::kDiffuse:
      s = SampleDiffuse(m, wo, u);
      break;
    case MaterialType::kCoatedDiffuse:
      s = SampleCoatedDiffuse(m, wo, uc, u);
      break;
    case MaterialType::kConductor:
      s = SampleConductor(m, wo, u);
      break;
    case MaterialType::kDielectric:
      s = SampleDielectric(m, wo, uc, u, mode);
      break;
    case MaterialType::kThinDielectric:
      s = SampleThinDielectric(m, wo, uc);
      break;
    case MaterialType::kDiffuseTransmission:
      s = SampleDiffuseTransmission(m, wo, uc, u);
      break;
    case MaterialType::kInterface:
      return std::nullopt;
  }
  // A sample the caller cannot use (zero pdf, grazing, overflow) is no sample
  if (!s || !(s->pdf > 0) || !std::isfinite(s->pdf) || !s->f.IsFinite() || !IsFinite(s->wi) ||
      s->wi.z == 0)
    return std::nullopt;
  return s;
}

Material CreateMaterial(const MaterialDesc& desc) {
  const ParamSet& params = desc.params;
  // The parser may have left the "string type" of MakeNamedMaterial in the list
  std::string type = params.GetOneString("type", "");
  if (!desc.type.empty()) type = desc.type;
  RejectUnsupportedParams(desc);

  Material m;
  m.name = desc.name;
  if (type == "diffuse") {
    m.type = MaterialType::kDiffuse;
    m.reflectance = GetAlbedo(desc, "reflectance", 0.5f);
    // Older pbrt-v4 files carry Oren-Nayar's "sigma"; only its default (Lambertian) is supported
    if (params.GetOneFloat("sigma", 0.f) != 0.f)
      throw SceneError(ParamLoc(desc, "sigma"),
                       "Oren-Nayar \"sigma\" is not supported (use 0 for Lambertian)");
  } else if (type == "coateddiffuse") {
    m.type = MaterialType::kCoatedDiffuse;
    m.reflectance = GetAlbedo(desc, "reflectance", 0.5f);
    ReadRoughness(desc, &m);
    m.thickness = params.GetOneFloat("thickness", 0.01f);
    if (!(m.thickness >= 0) || !std::isfinite(m.thickness))
      throw SceneError(ParamLoc(desc, "thickness"),
                       "\"thickness\" must be >= 0, got " + std::to_string(m.thickness));
    m.eta = RGB(GetInterfaceEta(desc));
    m.coat_albedo = GetAlbedo(desc, "albedo", 0.f);
    // Approximated (see "Coated diffuse" above): g is ignored; maxdepth and nsamples only
    // control pbrt's stochastic estimator, which the analytic model replaces.
    params.GetOneFloat("g", 0.f);
    params.GetOneInt("maxdepth", 10);
    params.GetOneInt("nsamples", 1);
  } else if (type == "conductor") {
    m.type = MaterialType::kConductor;
    if (params.Has("reflectance")) {
      if (params.Has("eta") || params.Has("k"))
        throw SceneError(desc.loc,
                         "conductor: \"reflectance\" cannot be combined with \"eta\" or \"k\"");
      m.conductor_uses_reflectance = true;
      m.reflectance = GetAlbedo(desc, "reflectance", 0.f);
    } else {
      // Defaults: pbrt-v4's "metal-Cu-eta" / "metal-Cu-k" projected to RGB
      m.eta = params.GetOneRGB("eta", SpectrumType::kUnbounded)
                  .value_or(RGB(0.200438f, 0.924033f, 1.102212f));
      m.k = params.GetOneRGB("k", SpectrumType::kUnbounded)
                .value_or(RGB(3.912949f, 2.452848f, 2.142188f));
    }
    ReadRoughness(desc, &m);
  } else if (type == "dielectric") {
    m.type = MaterialType::kDielectric;
    m.eta = RGB(GetInterfaceEta(desc));
    ReadRoughness(desc, &m);
  } else if (type == "thindielectric") {
    m.type = MaterialType::kThinDielectric;
    m.eta = RGB(GetInterfaceEta(desc));
  } else if (type == "diffusetransmission") {
    m.type = MaterialType::kDiffuseTransmission;
    float scale = params.GetOneFloat("scale", 1.f);
    if (!(scale >= 0) || !std::isfinite(scale))
      throw SceneError(ParamLoc(desc, "scale"),
                       "\"scale\" must be >= 0, got " + std::to_string(scale));
    m.reflectance = GetAlbedo(desc, "reflectance", 0.25f) * scale;
    m.transmittance = GetAlbedo(desc, "transmittance", 0.25f) * scale;
  } else if (type == "interface" || type == "none" || type.empty()) {
    // pbrt-v4: no material at all; rays continue through (media boundaries)
    m.type = MaterialType::kInterface;
  } else if (type == "coatedconductor" || type == "hair" || type == "measured" || type == "mix" ||
             type == "subsurface") {
    throw SceneError(desc.loc, "material type \"" + type + "\" is not supported yet");
  } else {
    throw SceneError(desc.loc, "unknown material type \"" + type + "\"");
  }
  params.ReportUnused("Material \"" + type + "\"");
  return m;
}

}  // namespace lightfarm
