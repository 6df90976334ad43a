#include "common/image/filter.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/util/error.h"

namespace lightfarm {
namespace {

// Normal density N(x; 0, sigma).
float Gaussian(float x, float sigma) {
  return std::exp(-(x * x) / (2.f * sigma * sigma)) / std::sqrt(2.f * kPi * sigma * sigma);
}

// ∫_{x0}^{x1} N(x; 0, sigma) dx, in double.
double GaussianIntegral(double x0, double x1, double sigma) {
  const double s = sigma * std::sqrt(2.0);
  return 0.5 * (std::erf(x1 / s) - std::erf(x0 / s));
}

float Sinc(float x) {
  if (std::abs(x) < 1e-5f) return 1.f - Sqr(kPi * x) / 6.f;
  return std::sin(kPi * x) / (kPi * x);
}

// Sinc windowed by a wider sinc (Lanczos), zero beyond the radius.
float WindowedSinc(float x, float radius, float tau) {
  if (std::abs(x) > radius) return 0.f;
  return Sinc(x) * Sinc(x / tau);
}

// Mitchell & Netravali 1988 cubic on [-2, 2]; integrates to 1.
float Mitchell1D(float x, float b, float c) {
  x = std::abs(x);
  if (x <= 1.f) {
    return ((12.f - 9.f * b - 6.f * c) * x * x * x + (-18.f + 12.f * b + 6.f * c) * x * x +
            (6.f - 2.f * b)) *
           (1.f / 6.f);
  }
  if (x <= 2.f) {
    return ((-b - 6.f * c) * x * x * x + (6.f * b + 30.f * c) * x * x + (-12.f * b - 48.f * c) * x +
            (8.f * b + 24.f * c)) *
           (1.f / 6.f);
  }
  return 0.f;
}

class BoxFilter final : public Filter {
 public:
  explicit BoxFilter(Vec2 radius) : Filter(radius) {}
  FilterType type() const override { return FilterType::kBox; }
  float Evaluate(Vec2 p) const override {
    return (std::abs(p.x) <= radius_.x && std::abs(p.y) <= radius_.y) ? 1.f : 0.f;
  }
  float Integral() const override { return 4.f * radius_.x * radius_.y; }
};

class TriangleFilter final : public Filter {
 public:
  explicit TriangleFilter(Vec2 radius) : Filter(radius) {}
  FilterType type() const override { return FilterType::kTriangle; }
  float Evaluate(Vec2 p) const override {
    return std::max(0.f, radius_.x - std::abs(p.x)) * std::max(0.f, radius_.y - std::abs(p.y));
  }
  float Integral() const override { return Sqr(radius_.x) * Sqr(radius_.y); }
};

// pbrt-v4: the Gaussian minus its value at the radius, so that it falls to 0 there.
class GaussianFilter final : public Filter {
 public:
  GaussianFilter(Vec2 radius, float sigma)
      : Filter(radius),
        sigma_(sigma),
        exp_x_(Gaussian(radius.x, sigma)),
        exp_y_(Gaussian(radius.y, sigma)) {}
  FilterType type() const override { return FilterType::kGaussian; }
  float Evaluate(Vec2 p) const override {
    if (std::abs(p.x) > radius_.x || std::abs(p.y) > radius_.y) return 0.f;
    return std::max(0.f, Gaussian(p.x, sigma_) - exp_x_) *
           std::max(0.f, Gaussian(p.y, sigma_) - exp_y_);
  }
  float Integral() const override {
    const double rx = radius_.x;
    const double ix = GaussianIntegral(-rx, rx, sigma_) - 2.0 * rx * double(exp_x_);
    const double ry = radius_.y;
    const double iy = GaussianIntegral(-ry, ry, sigma_) - 2.0 * ry * double(exp_y_);
    return static_cast<float>(ix * iy);
  }

 private:
  float sigma_, exp_x_, exp_y_;
};

class MitchellFilter final : public Filter {
 public:
  MitchellFilter(Vec2 radius, float b, float c) : Filter(radius), b_(b), c_(c) {}
  FilterType type() const override { return FilterType::kMitchell; }
  float Evaluate(Vec2 p) const override {
    return Mitchell1D(2.f * p.x / radius_.x, b_, c_) * Mitchell1D(2.f * p.y / radius_.y, b_, c_);
  }
  // The 1-D cubic integrates to 1 over [-2, 2]; the radius scales each axis by radius / 2.
  float Integral() const override { return radius_.x * radius_.y / 4.f; }

 private:
  float b_, c_;
};

class LanczosSincFilter final : public Filter {
 public:
  LanczosSincFilter(Vec2 radius, float tau)
      : Filter(radius),
        tau_(tau),
        integral_(static_cast<float>(Integral1D(radius.x) * Integral1D(radius.y))) {}
  FilterType type() const override { return FilterType::kLanczosSinc; }
  float Evaluate(Vec2 p) const override {
    return WindowedSinc(p.x, radius_.x, tau_) * WindowedSinc(p.y, radius_.y, tau_);
  }
  float Integral() const override { return integral_; }

 private:
  // No closed form: midpoint rule, 4096 intervals per pixel, summed in double.
  double Integral1D(float radius) const {
    const int n = std::max(1, static_cast<int>(std::ceil(2.f * radius * 4096.f)));
    const double r = radius;
    const double h = 2.0 * r / n;
    double sum = 0;
    for (int i = 0; i < n; ++i) {
      sum += double(WindowedSinc(static_cast<float>(-r + (i + 0.5) * h), radius, tau_));
    }
    return sum * h;
  }

  float tau_;
  float integral_;
};

void CheckPositive(FilterType type, const char* name, float value) {
  if (!(value > 0.f) || !std::isfinite(value)) {
    throw OptionError(std::string("filter \"") + FilterTypeName(type) + "\": parameter \"" + name +
                      "\" must be positive and finite, got " + std::to_string(value));
  }
}

}  // namespace

FilterType ParseFilterType(std::string_view name) {
  if (name == "box") return FilterType::kBox;
  if (name == "triangle") return FilterType::kTriangle;
  if (name == "gaussian") return FilterType::kGaussian;
  if (name == "mitchell") return FilterType::kMitchell;
  if (name == "sinc" || name == "lanczos") return FilterType::kLanczosSinc;
  throw OptionError("unknown pixel filter \"" + std::string(name) +
                    "\" (expected box, triangle, gaussian, mitchell or sinc)");
}

const char* FilterTypeName(FilterType type) {
  switch (type) {
    case FilterType::kBox:
      return "box";
    case FilterType::kTriangle:
      return "triangle";
    case FilterType::kGaussian:
      return "gaussian";
    case FilterType::kMitchell:
      return "mitchell";
    case FilterType::kLanczosSinc:
      return "sinc";
  }
  return "?";
}

Vec2 Filter::DefaultRadius(FilterType type) {
  switch (type) {
    case FilterType::kBox:
      return {0.5f, 0.5f};
    case FilterType::kTriangle:
      return {2.f, 2.f};
    case FilterType::kGaussian:
      return {1.5f, 1.5f};
    case FilterType::kMitchell:
      return {2.f, 2.f};
    case FilterType::kLanczosSinc:
      return {4.f, 4.f};
  }
  return {0.5f, 0.5f};
}

std::unique_ptr<Filter> Filter::Create(FilterType type) {
  return Create(type, DefaultRadius(type), FilterShape{});
}

std::unique_ptr<Filter> Filter::Create(FilterType type, Vec2 radius, const FilterShape& shape) {
  CheckPositive(type, "xradius", radius.x);
  CheckPositive(type, "yradius", radius.y);
  switch (type) {
    case FilterType::kBox:
      return std::make_unique<BoxFilter>(radius);
    case FilterType::kTriangle:
      return std::make_unique<TriangleFilter>(radius);
    case FilterType::kGaussian:
      CheckPositive(type, "sigma", shape.sigma);
      return std::make_unique<GaussianFilter>(radius, shape.sigma);
    case FilterType::kMitchell:
      if (!std::isfinite(shape.b) || !std::isfinite(shape.c)) {
        throw OptionError("filter \"mitchell\": parameters \"B\" and \"C\" must be finite");
      }
      return std::make_unique<MitchellFilter>(radius, shape.b, shape.c);
    case FilterType::kLanczosSinc:
      CheckPositive(type, "tau", shape.tau);
      return std::make_unique<LanczosSincFilter>(radius, shape.tau);
  }
  throw OptionError("unknown filter type");
}

// --- FilterSampler ------------------------------------------------------------------------

namespace {

// Normalises running sums `cdf` (size n+1, cdf[0] = 0) to end at exactly 1. A zero total
// becomes a uniform CDF so that the inversion below is always defined.
void NormaliseCdf(double* cdf, int n) {
  const double total = cdf[n];
  for (int i = 1; i <= n; ++i) cdf[i] = total > 0 ? cdf[i] / total : static_cast<double>(i) / n;
  cdf[n] = 1.0;
}

// Inverts a normalised piecewise-constant CDF: the cell i with cdf[i] <= u < cdf[i+1] and the
// position of u inside it, in [0, 1).
int InvertCdf(const double* cdf, int n, double u, double* fraction) {
  const int i =
      std::clamp(static_cast<int>(std::upper_bound(cdf, cdf + n + 1, u) - cdf) - 1, 0, n - 1);
  const double width = cdf[i + 1] - cdf[i];
  const double t = width > 0 ? (u - cdf[i]) / width : 0.5;
  *fraction = std::clamp(t, 0.0, std::nextafter(1.0, 0.0));
  return i;
}

}  // namespace

FilterSampler::FilterSampler(const Filter& filter, int samples_per_unit)
    : radius_(filter.radius()) {
  if (samples_per_unit <= 0) {
    throw OptionError("FilterSampler: samples_per_unit must be positive, got " +
                      std::to_string(samples_per_unit));
  }
  nx_ = std::max(1, static_cast<int>(static_cast<float>(samples_per_unit) * radius_.x));
  ny_ = std::max(1, static_cast<int>(static_cast<float>(samples_per_unit) * radius_.y));
  cell_area_ =
      (2.f * radius_.x / static_cast<float>(nx_)) * (2.f * radius_.y / static_cast<float>(ny_));

  // Tabulate f at the cell centres.
  f_.resize(static_cast<size_t>(nx_) * static_cast<size_t>(ny_));
  for (int y = 0; y < ny_; ++y) {
    const float py =
        -radius_.y + 2.f * radius_.y * (static_cast<float>(y) + 0.5f) / static_cast<float>(ny_);
    for (int x = 0; x < nx_; ++x) {
      const float px =
          -radius_.x + 2.f * radius_.x * (static_cast<float>(x) + 0.5f) / static_cast<float>(nx_);
      f_[static_cast<size_t>(y) * nx_ + x] = filter.Evaluate({px, py});
    }
  }
  for (float f : f_) positive_ = positive_ && !(f < 0.f);

  // Conditional CDFs of |f| along each row, and the marginal CDF of the row sums.
  row_cdf_.assign(static_cast<size_t>(ny_) * (nx_ + 1), 0.0);
  marginal_cdf_.assign(ny_ + 1, 0.0);
  for (int y = 0; y < ny_; ++y) {
    double* cdf = &row_cdf_[static_cast<size_t>(y) * (nx_ + 1)];
    for (int x = 0; x < nx_; ++x) {
      cdf[x + 1] = cdf[x] + std::abs(static_cast<double>(f_[static_cast<size_t>(y) * nx_ + x]));
    }
    marginal_cdf_[y + 1] = marginal_cdf_[y] + cdf[nx_];
    NormaliseCdf(cdf, nx_);
  }
  abs_sum_ = marginal_cdf_[ny_];
  if (!(abs_sum_ > 0) || !std::isfinite(abs_sum_)) {
    throw OptionError(std::string("filter \"") + FilterTypeName(filter.type()) +
                      "\" is zero (or not finite) everywhere on its sampling grid");
  }
  NormaliseCdf(marginal_cdf_.data(), ny_);
}

FilterSample FilterSampler::Sample(Vec2 u) const {
  // Choose the row from the marginal, then the cell within it, each with its offset in the cell.
  double fy = 0, fx = 0;
  const int y = InvertCdf(marginal_cdf_.data(), ny_, u.y, &fy);
  const int x = InvertCdf(&row_cdf_[static_cast<size_t>(y) * (nx_ + 1)], nx_, u.x, &fx);
  const Vec2 p(-radius_.x + 2.f * radius_.x * static_cast<float>((x + fx) / nx_),
               -radius_.y + 2.f * radius_.y * static_cast<float>((y + fy) / ny_));

  // pdf = |f_cell| / (Σ|f| · cell area), so f_cell / pdf = sign(f_cell) · ∫|f_tab| (pbrt-v4).
  const float f = f_[static_cast<size_t>(y) * nx_ + x];
  const float abs_integral = static_cast<float>(abs_sum_) * cell_area_;
  return {p, f == 0.f ? 0.f : std::copysign(abs_integral, f)};
}

int FilterSampler::CellX(float x) const {
  const float t = (x + radius_.x) / (2.f * radius_.x);
  return std::clamp(static_cast<int>(t * static_cast<float>(nx_)), 0, nx_ - 1);
}

int FilterSampler::CellY(float y) const {
  const float t = (y + radius_.y) / (2.f * radius_.y);
  return std::clamp(static_cast<int>(t * static_cast<float>(ny_)), 0, ny_ - 1);
}

float FilterSampler::Pdf(Vec2 p) const {
  if (std::abs(p.x) > radius_.x || std::abs(p.y) > radius_.y) return 0.f;
  const float f = f_[static_cast<size_t>(CellY(p.y)) * nx_ + CellX(p.x)];
  return static_cast<float>(std::abs(static_cast<double>(f)) /
                            (abs_sum_ * static_cast<double>(cell_area_)));
}

}  // namespace lightfarm
