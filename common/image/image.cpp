#include "common/image/image.h"

#include <stdexcept>
#include <string>

namespace lightfarm {

Image::Image(int w, int h, RGB fill) : width(w), height(h) {
  if (w < 0 || h < 0) {
    throw std::invalid_argument("invalid image size " + std::to_string(w) + "x" +
                                std::to_string(h));
  }
  pixels.assign(static_cast<size_t>(w) * static_cast<size_t>(h), fill);
}

double Image::MeanLuminance() const {
  if (pixels.empty()) return 0.0;
  double sum = 0.0;
  size_t n = 0;
  for (const RGB& p : pixels) {
    if (!p.IsFinite()) continue;  // a stray NaN in a reference must not poison the mean
    sum += static_cast<double>(p.Luminance());
    ++n;
  }
  return n > 0 ? sum / static_cast<double>(n) : 0.0;
}

size_t Image::CountNonFinite() const {
  size_t n = 0;
  for (const RGB& p : pixels) n += p.IsFinite() ? 0 : 1;
  return n;
}

}  // namespace lightfarm
