// A linear-RGB float image: the unit the film resolves to, the I/O functions read and write,
// and the error metrics compare.
#pragma once

#include <cstddef>
#include <vector>

#include "common/util/math.h"

namespace lightfarm {

// Row-major, y down: pixel (0, 0) is the top-left corner, pixel (x, y) is
// pixels[y * width + x]. Values are linear radiance (no tone mapping, no sRGB encoding).
struct Image {
  int width = 0, height = 0;
  std::vector<RGB> pixels;

  Image() = default;
  // A width × height image filled with `fill`. Throws std::invalid_argument for a negative size.
  Image(int w, int h, RGB fill = RGB(0.f));

  RGB& at(int x, int y) { return pixels[Index(x, y)]; }
  const RGB& at(int x, int y) const { return pixels[Index(x, y)]; }
  size_t Index(int x, int y) const {
    return static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x);
  }
  size_t PixelCount() const { return pixels.size(); }
  bool Empty() const { return pixels.empty(); }
  bool SameSize(const Image& o) const { return width == o.width && height == o.height; }

  // Mean of RGB::Luminance over all pixels, summed in double. 0 for an empty image.
  double MeanLuminance() const;  // over finite pixels only
  // Number of pixels with a NaN or infinite channel.
  size_t CountNonFinite() const;
};

}  // namespace lightfarm
