// The emitters a scene declares (pbrt-v4's lights): diffuse area lights on shapes, point and spot
// lights, distant lights and infinite (environment) lights, with what sampling them needs.
#pragma once

#include <cstdint>
#include <vector>

#include "common/util/math.h"
#include "common/util/transform.h"

namespace lightfarm {

// A diffuse area light: emission L on the front side (both sides if two_sided) of a shape.
struct AreaEmitter {
  uint32_t shape = 0;
  RGB L;  // radiance, already multiplied by "scale"
  bool two_sided = false;
  float area = 0;                    // total surface area
  std::vector<float> triangle_cdf;   // cumulative triangle areas (meshes), normalised
  // Emitted power Φ = π · A · L (· 2 when two-sided).
  RGB Power() const { return L * (kPi * area * (two_sided ? 2.f : 1.f)); }
};

// Point, spot, distant and infinite lights as the file gives them.
struct PointEmitter {
  Vec3 position;
  RGB intensity;                // I · scale
  bool spot = false;
  int medium = -1;              // the medium the light sits in (index into Scene::media())
  Vec3 axis{0, 0, 1};           // spot direction (world)
  float cos_falloff_start = 1, cos_falloff_end = -1;  // spot cone (smoothstep between)
  // pbrt-v4 spot falloff: smoothstep(cosFalloffEnd, cosFalloffStart, cos θ).
  float Falloff(Vec3 w_from_light) const;
};
struct DistantEmitter {
  int medium = -1;  // the medium its particles start in (the light's MediumInterface)
  Vec3 direction;  // direction the light travels (from "from" to "to")
  RGB L;           // irradiance scale: radiance arriving along -direction integrated = L·scale
};
struct InfiniteEmitter {
  int medium = -1;  // the medium its particles start in (the light's MediumInterface)
  RGB L{0.f};      // uniform radiance (when no image)
  Transform world_from_light, light_from_world;
  int width = 0, height = 0;  // equal-area octahedral image (pbrt-v4), empty for uniform
  std::vector<RGB> image;
  std::vector<float> pixel_cdf;  // luminance-proportional sampling over pixels
  float luminance_sum = 0;
  RGB scale{1.f};
  RGB Le(Vec3 w_world) const;  // radiance arriving from direction w (w points away from scene)
  // Samples a direction (pointing away from the scene) ∝ luminance; returns pdf (solid angle).
  Vec3 SampleDirection(Vec2 u, float* pdf) const;
  float Pdf(Vec3 w_world) const;
  RGB AverageRadiance() const;
};

}  // namespace lightfarm
