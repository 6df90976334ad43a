// The film: per-pixel weighted sums of radiance samples, resolved to an image.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "common/image/image.h"
#include "common/util/math.h"

namespace lightfarm {

// Sums of one pixel, in double so that the resolved value depends on the order in which
// samples and tiles arrive only through double rounding (far below float precision).
struct FilmPixel {
  double r = 0, g = 0, b = 0;  // Σ w·L
  double weight = 0;           // Σ w
};

// Pixel value = Σ w·L / Σ w over the samples added to that pixel, where w is the filter weight
// f(p)/pdf(p) of the sample (FilterSampler). Samples are not splatted to neighbours: each
// belongs to the one pixel whose centre its filter offset was measured from.
//
// Not thread-safe: AddSample and Merge mutate without synchronisation. Give each thread or
// task its own Film and Merge them in a fixed order; bit-identical results across thread
// counts are the caller's responsibility (DESIGN.md, Determinism).
class Film {
 public:
  Film() = default;
  // Throws std::invalid_argument for a negative size.
  Film(int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }
  int PixelIndex(int x, int y) const { return y * width_ + x; }

  // Adds w·L and w to pixel `pixel_index` (y * width + x). A sample whose radiance or weight
  // is NaN or infinite is dropped and counted in nan_samples(); it never reaches the image.
  // Throws std::out_of_range for an index outside the film.
  void AddSample(int pixel_index, RGB L, float weight);

  // Adds another film's sums and NaN count. Throws std::invalid_argument if sizes differ.
  void Merge(const Film& other);

  // Σ w·L / Σ w per pixel, as float; 0 where Σ w is 0 (no samples).
  Image Resolve() const;

  // Samples dropped by AddSample because L or w was not finite (including merged films').
  uint64_t nan_samples() const { return nan_samples_; }

  // Raw sums, e.g. to ship a tile between processes; AddPixelSums is Merge for one pixel.
  std::span<const FilmPixel> pixels() const { return pixels_; }
  void AddPixelSums(int pixel_index, const FilmPixel& sums);

 private:
  FilmPixel& PixelAt(int pixel_index);

  int width_ = 0, height_ = 0;
  std::vector<FilmPixel> pixels_;
  uint64_t nan_samples_ = 0;
};

}  // namespace lightfarm
