#include "common/scene/lights.h"

#include <algorithm>

#include "common/util/sampling.h"

namespace lightfarm {

float PointEmitter::Falloff(Vec3 w_from_light) const {
  if (!spot) return 1.f;
  float cos_t = Dot(w_from_light, axis);
  if (cos_t >= cos_falloff_start) return 1.f;
  if (cos_t <= cos_falloff_end) return 0.f;
  float t = (cos_t - cos_falloff_end) / (cos_falloff_start - cos_falloff_end);
  return t * t * (3 - 2 * t);  // smoothstep, as pbrt-v4
}

RGB InfiniteEmitter::Le(Vec3 w_world) const {
  if (image.empty()) return L * scale;
  Vec3 wl = Normalize(light_from_world.ApplyVector(w_world));
  Vec2 uv = EqualAreaSphereToSquare(wl);
  int x = std::min(int(uv.x * width), width - 1), y = std::min(int(uv.y * height), height - 1);
  return image[size_t(y) * width + x] * scale;
}

Vec3 InfiniteEmitter::SampleDirection(Vec2 u, float* pdf) const {
  if (image.empty()) {
    *pdf = kUniformSpherePdf;
    return SampleUniformSphere(u);
  }
  // Pick a pixel ∝ luminance (binary search in the CDF), then a uniform point in it; the
  // equal-area map makes the solid-angle pdf = p_pixel * npixels / (4π).
  size_t n = pixel_cdf.size();
  size_t i = std::upper_bound(pixel_cdf.begin(), pixel_cdf.end(), u.x * pixel_cdf.back()) -
             pixel_cdf.begin();
  i = std::min(i, n - 1);
  float lo = i == 0 ? 0.f : pixel_cdf[i - 1];
  float p_pixel = (pixel_cdf[i] - lo) / pixel_cdf.back();
  float ux = (u.x * pixel_cdf.back() - lo) / std::max(pixel_cdf[i] - lo, 1e-30f);
  ux = Clamp(ux, 0.f, 0x1.fffffep-1f);
  int x = int(i % width), y = int(i / width);
  Vec2 st{(x + ux) / width, (y + u.y) / height};
  *pdf = p_pixel * float(n) * kInv4Pi;
  return Normalize(world_from_light.ApplyVector(EqualAreaSquareToSphere(st)));
}

float InfiniteEmitter::Pdf(Vec3 w_world) const {
  if (image.empty()) return kUniformSpherePdf;
  Vec3 wl = Normalize(light_from_world.ApplyVector(w_world));
  Vec2 uv = EqualAreaSphereToSquare(wl);
  int x = std::min(int(uv.x * width), width - 1), y = std::min(int(uv.y * height), height - 1);
  size_t i = size_t(y) * width + x;
  float lo = i == 0 ? 0.f : pixel_cdf[i - 1];
  return (pixel_cdf[i] - lo) / pixel_cdf.back() * float(pixel_cdf.size()) * kInv4Pi;
}

RGB InfiniteEmitter::AverageRadiance() const {
  if (image.empty()) return L * scale;
  RGBAccum sum;
  for (const RGB& c : image) sum.Add(c);
  return sum.ToRGB() * (scale / float(image.size()));
}

}  // namespace lightfarm
