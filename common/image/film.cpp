#include "common/image/film.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace lightfarm {

Film::Film(int width, int height) : width_(width), height_(height) {
  if (width < 0 || height < 0) {
    throw std::invalid_argument("invalid film size " + std::to_string(width) + "x" +
                                std::to_string(height));
  }
  pixels_.resize(static_cast<size_t>(width) * static_cast<size_t>(height));
}

FilmPixel& Film::PixelAt(int pixel_index) {
  if (pixel_index < 0 || static_cast<size_t>(pixel_index) >= pixels_.size()) {
    throw std::out_of_range("film pixel index " + std::to_string(pixel_index) + " outside a " +
                            std::to_string(width_) + "x" + std::to_string(height_) + " film");
  }
  return pixels_[static_cast<size_t>(pixel_index)];
}

void Film::AddSample(int pixel_index, RGB L, float weight) {
  FilmPixel& pixel = PixelAt(pixel_index);
  // Drop non-finite samples: one NaN would poison the pixel's sums forever.
  if (!L.IsFinite() || !std::isfinite(weight)) {
    ++nan_samples_;
    return;
  }
  const double w = weight;
  pixel.r += w * static_cast<double>(L.r);
  pixel.g += w * static_cast<double>(L.g);
  pixel.b += w * static_cast<double>(L.b);
  pixel.weight += w;
}

void Film::AddPixelSums(int pixel_index, const FilmPixel& sums) {
  FilmPixel& pixel = PixelAt(pixel_index);
  pixel.r += sums.r;
  pixel.g += sums.g;
  pixel.b += sums.b;
  pixel.weight += sums.weight;
}

void Film::Merge(const Film& other) {
  if (other.width_ != width_ || other.height_ != height_) {
    throw std::invalid_argument("cannot merge a " + std::to_string(other.width_) + "x" +
                                std::to_string(other.height_) + " film into a " +
                                std::to_string(width_) + "x" + std::to_string(height_) + " film");
  }
  for (size_t i = 0; i < pixels_.size(); ++i) {
    pixels_[i].r += other.pixels_[i].r;
    pixels_[i].g += other.pixels_[i].g;
    pixels_[i].b += other.pixels_[i].b;
    pixels_[i].weight += other.pixels_[i].weight;
  }
  nan_samples_ += other.nan_samples_;
}

Image Film::Resolve() const {
  Image image(width_, height_);
  for (size_t i = 0; i < pixels_.size(); ++i) {
    const FilmPixel& p = pixels_[i];
    if (p.weight == 0) continue;
    const double inv = 1.0 / p.weight;
    image.pixels[i] = RGB(static_cast<float>(p.r * inv), static_cast<float>(p.g * inv),
                          static_cast<float>(p.b * inv));
  }
  return image;
}

}  // namespace lightfarm
