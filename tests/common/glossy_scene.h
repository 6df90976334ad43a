// scenes/glossy-plane (a near-specular plane reflecting a small area light in front of a
// diffuse backdrop) with the plane's Trowbridge-Reitz roughness set to `alpha`, for the
// sharp-lobe tests (tests/scenes/test_sharp_lobes.cpp, the farm tests); 48×32 pixels, box
// filter. Regions of the image: the light's reflection (blob), the backdrop and the plane
// around the reflection.
#pragma once

#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include "common/image/image.h"
#include "tests/common/test_util.h"

namespace lightfarm::testing {

inline std::string GlossyPlane(float alpha) {
  std::ifstream in(SourcePath("scenes/glossy-plane/scene.pbrt"));
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string key = "\"float roughness\" 0.02";
  const size_t at = s.find(key);
  if (at == std::string::npos) throw std::runtime_error("scenes/glossy-plane/scene.pbrt: no roughness to set");
  return s.replace(at, key.size(), "\"float roughness\" " + std::to_string(alpha));
}

// The same scene with the plane a clear coat of Trowbridge-Reitz roughness `roughness` (0: a
// smooth, delta coat) over a grey diffuse base: a mixed vertex for every camera sample that
// reaches the plane (tests/scenes/test_split_vertices.cpp).
inline std::string CoatedPlane(float roughness) {
  std::string s = GlossyPlane(0.02f);
  const std::string key = "Material \"conductor\"";
  const size_t at = s.find(key);
  const size_t end = s.find('\n', at);
  if (at == std::string::npos || end == std::string::npos)
    throw std::runtime_error("scenes/glossy-plane/scene.pbrt: no plane material to replace");
  return s.replace(at, end - at,
                   "Material \"coateddiffuse\" \"rgb reflectance\" [0.5 0.5 0.5] \"float roughness\" " +
                       std::to_string(roughness) + " \"bool remaproughness\" false");
}

// Pixel rectangles [x0, x0 + w) × [y0, y0 + h) of GlossyPlane's image.
struct PixelRect {
  int x0, y0, w, h;
};
inline double Lum(const RGB& c) { return double(c.Luminance()); }

// The mean luminance of an image over a pixel rectangle.
inline double RegionMean(const Image& img, PixelRect r) {
  double s = 0;
  for (int y = r.y0; y < r.y0 + r.h; ++y)
    for (int x = r.x0; x < r.x0 + r.w; ++x) s += Lum(img.at(x, y));
  return s / double(r.w * r.h);
}

inline constexpr PixelRect kGlossyBlob{16, 24, 16, 8}, kGlossyBackdrop{0, 4, 48, 10}, kGlossyPlane{0, 16, 48, 6};

}  // namespace lightfarm::testing
