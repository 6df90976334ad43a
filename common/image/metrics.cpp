#include "common/image/metrics.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace lightfarm {
namespace {

std::string SizeString(const Image& image) {
  return std::to_string(image.width) + "x" + std::to_string(image.height);
}

void CheckComparable(const Image& reference, const Image& image) {
  if (!reference.SameSize(image)) {
    throw std::runtime_error("image sizes differ: " + SizeString(reference) + " vs " +
                             SizeString(image));
  }
  if (reference.Empty()) throw std::runtime_error("cannot compare empty images");
  if (size_t n = image.CountNonFinite()) {
    throw std::runtime_error("image has " + std::to_string(n) +
                             " pixels with NaN or infinite values");
  }
}

// OKLab (Ottosson 2020) to linear sRGB.
RGB OklabToLinearSRGB(double L, double a, double b) {
  const double l = std::pow(L + 0.3963377774 * a + 0.2158037573 * b, 3.0);
  const double m = std::pow(L - 0.1055613458 * a - 0.0638541728 * b, 3.0);
  const double s = std::pow(L - 0.0894841775 * a - 1.2914855480 * b, 3.0);
  return RGB(static_cast<float>(4.0767416621 * l - 3.3077115913 * m + 0.2309699292 * s),
             static_cast<float>(-1.2684380046 * l + 2.6097574011 * m - 0.3413193965 * s),
             static_cast<float>(-0.0041960863 * l - 0.7034186147 * m + 1.7076147010 * s));
}

bool InGamut(RGB c) {
  return c.r >= 0.f && c.g >= 0.f && c.b >= 0.f && c.r <= 1.f && c.g <= 1.f && c.b <= 1.f;
}

// The colour map is defined in OKLab polar form (lightness, chroma, hue):
//  - lightness rises linearly from 0.12 to 0.97, so equal steps in error look like equal steps;
//  - hue turns from violet (290°) through red and orange to yellow (110°);
//  - chroma peaks mid-scale and falls towards both ends (near-black start, pale-yellow end).
// Chroma that falls outside the sRGB gamut is reduced (bisection) at constant lightness and
// hue, so the lightness ramp survives the gamut mapping.
RGB ColorMapEntry(double t) {
  const double L = 0.12 + 0.85 * t;
  const double hue = (290.0 + 180.0 * t) * (3.14159265358979323846 / 180.0);
  const double chroma =
      0.03 + 0.19 * std::sin(3.14159265358979323846 * std::pow(t, 0.75)) + 0.08 * t;
  auto at = [&](double c) { return OklabToLinearSRGB(L, c * std::cos(hue), c * std::sin(hue)); };
  if (InGamut(at(chroma))) return at(chroma);
  double lo = 0.0, hi = chroma;
  for (int i = 0; i < 30; ++i) {
    const double mid = 0.5 * (lo + hi);
    (InGamut(at(mid)) ? lo : hi) = mid;
  }
  const RGB c = at(lo);
  return RGB(Clamp(c.r, 0.f, 1.f), Clamp(c.g, 0.f, 1.f), Clamp(c.b, 0.f, 1.f));
}

constexpr int kColorMapSize = 256;

const std::array<RGB, kColorMapSize>& ColorMap() {
  static const std::array<RGB, kColorMapSize> table = [] {
    std::array<RGB, kColorMapSize> t;
    for (int i = 0; i < kColorMapSize; ++i) t[i] = ColorMapEntry(i / double(kColorMapSize - 1));
    return t;
  }();
  return table;
}

}  // namespace

ErrorMetrics CompareImages(const Image& reference, const Image& image, float exclude_above) {
  CheckComparable(reference, image);
  double diff2 = 0, ref2 = 0, diff1 = 0, ref1 = 0;
  size_t excluded = 0, bright = 0;
  for (size_t i = 0; i < reference.PixelCount(); ++i) {
    if (!reference.pixels[i].IsFinite()) {
      ++excluded;
      continue;
    }
    if (reference.pixels[i].Max() > exclude_above) {
      ++bright;
      continue;
    }
    for (int c = 0; c < 3; ++c) {
      const double r = reference.pixels[i][c];
      const double d = r - static_cast<double>(image.pixels[i][c]);
      diff2 += d * d;
      ref2 += r * r;
      diff1 += std::abs(d);
      ref1 += std::abs(r);
    }
  }
  if (ref2 == 0) {
    throw std::runtime_error("reference image is all zero: relative errors are undefined");
  }
  ErrorMetrics m;
  size_t lit = 0;
  for (int y = 0; y < reference.height; ++y)
    for (int x = 0; x < reference.width; ++x) {
      const RGB& r = reference.at(x, y);
      if (!r.IsFinite() || r.Max() > exclude_above || !(r.Luminance() > 0.f)) continue;
      ++lit;
      float lo = kInfinity, hi = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= reference.width || yy >= reference.height) continue;
          const RGB& n = reference.at(xx, yy);
          if (!n.IsFinite()) continue;
          lo = std::min(lo, n.Luminance());
          hi = std::max(hi, n.Luminance());
        }
      const float v = image.at(x, y).Luminance();
      m.dark_specks += v < 0.3f * lo;
      m.bright_specks += v > 3.f * hi;
    }
  m.speck_share = lit > 0 ? double(m.dark_specks + m.bright_specks) / double(lit) : 0.0;
  m.rel_l2 = std::sqrt(diff2 / ref2);
  m.rel_l1 = diff1 / ref1;
  m.rmse = std::sqrt(diff2 / (3.0 * static_cast<double>(reference.PixelCount() - excluded - bright)));
  m.excluded_pixels = excluded;
  m.excluded_bright = bright;
  return m;
}

RGB HeatmapColor(float t) {
  if (!(t > 0.f)) t = 0.f;  // also NaN
  const float x = std::min(t, 1.f) * (kColorMapSize - 1);
  const int i = std::min(static_cast<int>(x), kColorMapSize - 2);
  const float f = x - static_cast<float>(i);
  const auto& map = ColorMap();
  return map[i] * (1.f - f) + map[i + 1] * f;
}

Image ErrorHeatmap(const Image& reference, const Image& image, float max_error) {
  CheckComparable(reference, image);
  if (!(max_error > 0.f) || !std::isfinite(max_error)) {
    throw std::runtime_error("heatmap scale must be positive, got " + std::to_string(max_error));
  }
  const double mean = reference.MeanLuminance();
  if (!(mean > 0)) {
    throw std::runtime_error(
        "reference image has zero mean luminance: relative errors are undefined");
  }
  const double scale = 1.0 / (mean * static_cast<double>(max_error));
  Image heatmap(reference.width, reference.height);
  for (size_t i = 0; i < reference.PixelCount(); ++i) {
    if (!reference.pixels[i].IsFinite()) continue;  // excluded, as in CompareImages
    const RGB diff = reference.pixels[i] - image.pixels[i];
    const RGB abs_diff(std::abs(diff.r), std::abs(diff.g), std::abs(diff.b));
    heatmap.pixels[i] = HeatmapColor(static_cast<float>(double(abs_diff.Luminance()) * scale));
  }
  return heatmap;
}

}  // namespace lightfarm
