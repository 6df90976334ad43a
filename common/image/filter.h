// Pixel reconstruction filters, as pbrt-v4 defines them (pbrt-v4 book, Sec. 8.8), and filter
// importance sampling (pbrt-v4's FilterSampler).
//
// How the film uses them: a camera sample is taken at offset p (from FilterSampler::Sample)
// from the centre of the pixel it belongs to, and carries weight w = f(p) / pdf(p). The pixel
// value is Σ w·L / Σ w over the samples of that pixel (see film.h). Each sample belongs to
// exactly one pixel: the one whose centre p is measured from.
#pragma once

#include <memory>
#include <string_view>
#include <vector>

#include "common/util/math.h"

namespace lightfarm {

enum class FilterType { kBox, kTriangle, kGaussian, kMitchell, kLanczosSinc };

// pbrt-v4 names: "box", "triangle", "gaussian", "mitchell", "sinc" ("lanczos" is accepted too).
// Throws OptionError listing the valid names.
FilterType ParseFilterType(std::string_view name);
const char* FilterTypeName(FilterType type);

// Shape parameters beyond the radius, with pbrt-v4's names and defaults. Each filter reads
// only its own: gaussian "sigma", mitchell "B" and "C", sinc "tau".
struct FilterShape {
  float sigma = 0.5f;
  float b = 1.f / 3.f;
  float c = 1.f / 3.f;
  float tau = 3.f;
};

class Filter {
 public:
  virtual ~Filter() = default;

  // pbrt-v4 default radius: box 0.5, triangle 2, gaussian 1.5, mitchell 2, sinc 4 (both axes).
  static Vec2 DefaultRadius(FilterType type);
  // A filter with the default radius and shape.
  static std::unique_ptr<Filter> Create(FilterType type);
  // Throws OptionError naming the filter, parameter and value if the radius or a shape
  // parameter is not positive and finite.
  static std::unique_ptr<Filter> Create(FilterType type, Vec2 radius,
                                        const FilterShape& shape = {});

  virtual FilterType type() const = 0;
  // Half-extent of the support: f is zero outside [-radius.x, radius.x] × [-radius.y, radius.y].
  Vec2 radius() const { return radius_; }
  // f(p) for an offset p from the pixel centre, in pixels. May be negative (mitchell, sinc).
  virtual float Evaluate(Vec2 p) const = 0;
  // ∫ f over the support: analytic for box, triangle, gaussian and mitchell, numeric for sinc.
  virtual float Integral() const = 0;

 protected:
  explicit Filter(Vec2 radius) : radius_(radius) {}
  Vec2 radius_;
};

struct FilterSample {
  Vec2 p;        // offset from the pixel centre, within ±radius
  float weight;  // f / pdf; negative where f is
};

// Samples offsets with density proportional to |f|, as pbrt-v4's FilterSampler: f is tabulated
// at the centres of a grid of `samples_per_unit` cells per unit of radius on each axis (so 32
// gives 64·radius cells across the support, as in pbrt-v4), and a 2-D
// piecewise-constant distribution is built on it. As in pbrt-v4 the weight is the tabulated
// value of the chosen cell over the pdf, so |weight| = ∫|f_tab| is the same for every sample
// (lowest variance) and only its sign varies; E[weight] = ∫ f_tab ≈ Filter::Integral().
// Immutable after construction: Sample() may be called from many threads.
class FilterSampler {
 public:
  explicit FilterSampler(const Filter& filter, int samples_per_unit = 32);

  // u ∈ [0, 1)²  →  an offset within the filter's radius and its weight.
  FilterSample Sample(Vec2 u) const;
  // Density of Sample() at p, per unit area of offset; 0 outside the support.
  float Pdf(Vec2 p) const;
  Vec2 radius() const { return radius_; }
  // Whether every sample's weight is positive (no negative lobe in the tabulated filter).
  bool positive() const { return positive_; }

 private:
  int CellX(float x) const;
  int CellY(float y) const;

  Vec2 radius_;
  int nx_ = 0, ny_ = 0;
  std::vector<float> f_;              // tabulated f at cell centres, row-major (y, x)
  std::vector<double> row_cdf_;       // per row: nx_+1 entries of the conditional CDF of |f|
  std::vector<double> marginal_cdf_;  // ny_+1 entries of the CDF of row sums of |f|
  double abs_sum_ = 0;                // Σ |f_tab| over all cells
  float cell_area_ = 0;               // area of one cell, pixels²
  bool positive_ = true;
};

}  // namespace lightfarm
