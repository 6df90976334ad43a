// Materials and their BSDFs, evaluated in the local shading frame (z = shading normal), with
// pbrt-v4's conventions: f(wo, wi) excludes the cosine; wo points away from the surface towards
// the viewer (or the previous path vertex), wi towards the light (or the next vertex).
//
// A Material is a plain value (no virtual dispatch): the lighting matrix evaluates billions of
// f(wo, wi) and a switch on a small tag keeps that cheap and easy to serialise for the farm.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "common/scene/scene_description.h"
#include "common/util/math.h"

namespace lightfarm {

enum BxDFFlags : uint32_t {
  kBxDFUnset = 0,
  kBxDFReflection = 1 << 0,
  kBxDFTransmission = 1 << 1,
  kBxDFDiffuse = 1 << 2,
  kBxDFGlossy = 1 << 3,
  kBxDFSpecular = 1 << 4,
};

// Radiance: camera paths (adjoint of importance); Importance: particle tracing from lights.
// They differ for refraction (the 1/eta^2 radiance scaling) and shading normals.
enum class TransportMode { kRadiance, kImportance };

enum class MaterialType : uint8_t {
  kDiffuse,
  kCoatedDiffuse,
  kConductor,
  kDielectric,
  kThinDielectric,
  kDiffuseTransmission,
  kInterface,  // no surface: rays pass through (media boundaries)
};

struct Material {
  MaterialType type = MaterialType::kDiffuse;
  RGB reflectance{0.5f};    // diffuse, coateddiffuse, diffusetransmission (already * scale)
  RGB transmittance{0.f};   // diffusetransmission (already * scale)
  RGB eta{1.5f};            // dielectric: eta.r used (no dispersion); conductor: complex IOR real part
  RGB k{0.f};               // conductor: imaginary part
  bool conductor_uses_reflectance = false;  // conductor given "reflectance" instead of eta/k
  float alpha_x = 0, alpha_y = 0;           // Trowbridge-Reitz roughness (after remapping)
  float thickness = 0.01f;  // coateddiffuse layer thickness (attenuation of the diffuse base)
  RGB coat_albedo{0.f};     // coateddiffuse medium albedo (only 0 supported exactly; see .cpp)
  // The many-light split (docs/rendering.md, "Sharp lobes"): a glossy lobe whose roughness
  // max(alpha_x, alpha_y) is below this is a *sharp* lobe, sampled as a delta lobe is (flagged
  // kBxDFSpecular, with its true f and pdf) and never evaluated by EvalBSDF / PdfBSDF. 0: none.
  float sharp_alpha = 0;
  std::string name;         // for messages
};

// Creates a Material from its scene description; reads and checks every parameter and calls
// ReportUnused, so unknown or unsupported parameters are SceneErrors with file:line.
Material CreateMaterial(const MaterialDesc& desc);

// The lobes a material has (union of BxDFFlags).
uint32_t MaterialFlags(const Material& m);
// True if the material has no non-delta lobe (camera paths continue through it).
inline bool IsPurelySpecular(uint32_t flags) {
  return (flags & (kBxDFDiffuse | kBxDFGlossy)) == 0;
}

// f(wo, wi); zero for delta lobes.
RGB EvalBSDF(const Material& m, Vec3 wo, Vec3 wi, TransportMode mode);
// Solid-angle pdf of SampleBSDF producing wi (non-delta lobes only).
float PdfBSDF(const Material& m, Vec3 wo, Vec3 wi, TransportMode mode);

struct BSDFSample {
  RGB f;          // BSDF value (for delta lobes: the delta's weight, so f*|cos|/pdf is the throughput)
  Vec3 wi;
  float pdf = 0;  // solid-angle pdf, or the discrete probability of a delta lobe
  uint32_t flags = 0;  // the sampled lobe
  float eta = 1;       // relative IOR for transmission (for Russian roulette scaling)
  bool IsSpecular() const { return (flags & kBxDFSpecular) != 0; }
};
// Samples wi given wo. uc picks the lobe, u the direction. nullopt when sampling fails.
std::optional<BSDFSample> SampleBSDF(const Material& m, Vec3 wo, float uc, Vec2 u,
                                     TransportMode mode);

// Probability that SampleBSDF(m, wo, uc, ...) picks a delta lobe. Contract: for a material with
// both delta and non-delta lobes (a smooth coateddiffuse) SampleBSDF picks the delta lobe exactly
// when uc < this value, so a caller can split paths between the lobes without bias (camera paths
// follow the mirror lobe with this probability and become receivers otherwise). 1 for purely
// specular materials, 0 for materials without a delta lobe.
float SpecularSamplingProbability(const Material& m, Vec3 wo);

// For a material whose only lobes are two deltas chosen by a discrete probability (a smooth
// dielectric: reflection and refraction), the probability r that SampleBSDF picks reflection:
// it does exactly when uc < r, and the sample's pdf is that discrete probability (r, or 1 − r),
// so a caller can follow both lobes, each with weight f·|cos|. -1 for every other material, and
// where only one lobe is possible (total internal reflection, an index-matched interface).
float DeltaReflectionProbability(const Material& m, Vec3 wo);

// Whether the material's glossy lobe (if any) behaves as a delta lobe: perfectly smooth, or
// sharp under the many-light split (Material::sharp_alpha).
bool ActsAsDelta(const Material& m);
// Whether the material has a glossy lobe the split made sharp.
bool HasSharpLobe(const Material& m);
// True if the material has a microfacet lobe that is neither smooth nor sharp: one the columns
// evaluate, and a near-field sharp twin could sample instead (Scene::SetSharpAlpha).
bool HasRoughMicrofacetLobe(const Material& m);
// The sharp lobe alone, as SampleBSDF samples it: its f, and its pdf including the probability
// of choosing it (SpecularSamplingProbability); zero unless HasSharpLobe. For next-event
// estimation at a sharp vertex and the MIS weights of both strategies there.
RGB EvalSharpLobe(const Material& m, Vec3 wo, Vec3 wi, TransportMode mode);
float PdfSharpLobe(const Material& m, Vec3 wo, Vec3 wi);

// Trowbridge-Reitz alpha from pbrt's "roughness" (remaproughness true): alpha = sqrt(r).
float RoughnessToAlpha(float roughness);
// Microfacet lobes with alpha below this are treated as perfectly specular (pbrt-v4's value).
inline constexpr float kEffectivelySmoothAlpha = 1e-3f;

}  // namespace lightfarm
