// Spectra to linear sRGB. lightfarm renders in RGB, so every spectral value a pbrt-v4 file
// gives (blackbody emitters, measured spectra, named metal and glass data) is projected once,
// at parse time, through the CIE 1931 observer and the sRGB primaries.
#include <algorithm>
#include <array>
#include <cmath>
#include <string_view>

#include "common/scene/params.h"

namespace lightfarm {

namespace {

// Wavelength range and step of every spectral integral below (pbrt-v4 uses the same range).
constexpr double kLambdaMin = 360.0, kLambdaMax = 830.0;
constexpr int kLambdaSamples = 471;  // 1 nm steps, both ends included

// Piecewise Gaussian with different widths left and right of the mean.
double SplitGaussian(double x, double mu, double sigma_left, double sigma_right) {
  double t = (x - mu) / (x < mu ? sigma_left : sigma_right);
  return std::exp(-0.5 * t * t);
}

// CIE 1931 2-degree colour-matching functions, multi-lobe analytic fit of Wyman, Sloan and
// Shirley 2013 ("Simple Analytic Approximations to the CIE XYZ Color Matching Functions",
// JCGT 2(2)), Eq. 2. Its error is well below what an RGB renderer can show, and it spares a
// 471-entry table per function.
struct XYZ {
  double x = 0, y = 0, z = 0;
};

XYZ ColorMatching(double lambda) {
  return {1.056 * SplitGaussian(lambda, 599.8, 37.9, 31.0) +
              0.362 * SplitGaussian(lambda, 442.0, 16.0, 26.7) -
              0.065 * SplitGaussian(lambda, 501.1, 20.4, 26.2),
          0.821 * SplitGaussian(lambda, 568.8, 46.9, 40.5) +
              0.286 * SplitGaussian(lambda, 530.9, 16.3, 31.1),
          1.217 * SplitGaussian(lambda, 437.0, 11.8, 36.0) +
              0.681 * SplitGaussian(lambda, 459.0, 26.0, 13.8)};
}

// Integrates f(lambda) against the colour-matching functions (1 nm Riemann sum).
template <typename F>
XYZ IntegrateXYZ(F&& f) {
  XYZ sum;
  for (int i = 0; i < kLambdaSamples; ++i) {
    double lambda = kLambdaMin + i;
    double v = f(lambda);
    XYZ cmf = ColorMatching(lambda);
    sum.x += v * cmf.x;
    sum.y += v * cmf.y;
    sum.z += v * cmf.z;
  }
  return sum;
}

// XYZ to linear sRGB (IEC 61966-2-1 primaries, D65 white).
std::array<double, 3> XYZToLinearSRGB(const XYZ& c) {
  return {3.2404542 * c.x - 1.5371385 * c.y - 0.4985314 * c.z,
          -0.9692660 * c.x + 1.8760108 * c.y + 0.0415560 * c.z,
          0.0556434 * c.x - 0.2040259 * c.y + 1.0572252 * c.z};
}

// The RGB of the constant spectrum 1, per channel. A flat spectrum is the equal-energy
// illuminant E, which the D65-adapted sRGB observer sees as slightly pink (~1.20, 0.95, 0.91).
// Dividing by this triple white-balances E to the film's white, so that a flat reflectance of c
// is RGB(c, c, c) and a flat emission spectrum is neutral, which is what a scene author writing
// "spectrum" [ 400 0.5 700 0.5 ] means. (pbrt-v4 integrates reflectances against D65 instead;
// the difference is a slight tint on strongly coloured spectra, invisible on grey.)
const std::array<double, 3>& FlatSpectrumRGB() {
  static const std::array<double, 3> rgb =
      XYZToLinearSRGB(IntegrateXYZ([](double) { return 1.0; }));
  return rgb;
}

// Planck's law: spectral radiance of a blackbody, lambda in nm, in W / (m^2 sr m).
double Planck(double lambda_nm, double kelvin) {
  constexpr double c = 299792458.0;     // speed of light, m/s
  constexpr double h = 6.62607015e-34;  // Planck constant, J s
  constexpr double kb = 1.380649e-23;   // Boltzmann constant, J/K
  double l = lambda_nm * 1e-9;
  // expm1 keeps precision for very hot bodies, where the exponent is tiny.
  return (2 * h * c * c) / (std::pow(l, 5) * std::expm1((h * c) / (l * kb * kelvin)));
}

RGB ToRGB(const std::array<double, 3>& c) {
  return {static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2])};
}

}  // namespace

RGB BlackbodyToRGB(float kelvin) {
  if (!(kelvin > 0)) return RGB(0.f);
  double t = kelvin;
  std::array<double, 3> rgb = XYZToLinearSRGB(IntegrateXYZ([t](double l) { return Planck(l, t); }));
  // Very red (< ~1900 K) and very blue bodies lie outside the sRGB gamut; negative radiance
  // would break every estimator downstream, so clip before normalising.
  for (double& v : rgb) v = std::max(0.0, v);
  double m = std::max({rgb[0], rgb[1], rgb[2]});
  if (!(m > 0) || !std::isfinite(m)) return RGB(0.f);
  // pbrt-v4's BlackbodySpectrum peaks at 1; here the colour is what matters, so the RGB maximum
  // is 1 and the light's "scale"/"power" sets the brightness. No white balance: 6500 K is
  // near-white, 2700 K is orange, as a D65-adapted viewer sees them.
  return ToRGB({rgb[0] / m, rgb[1] / m, rgb[2] / m});
}

RGB SampledSpectrumToRGB(const std::vector<double>& lambda_value_pairs, SpectrumType type) {
  size_t n = lambda_value_pairs.size() / 2;
  if (n == 0) return RGB(0.f);
  auto lambda_at = [&](size_t i) { return lambda_value_pairs[2 * i]; };
  auto value_at = [&](size_t i) { return lambda_value_pairs[2 * i + 1]; };

  // Piecewise-linear interpolation. Outside the given range the end values are held: measured
  // data often stops at 400 or 700 nm, and zero tails (pbrt-v4's choice) would tint the result
  // by the part of the colour-matching functions they cut off.
  auto eval = [&](double lambda) {
    if (lambda <= lambda_at(0)) return value_at(0);
    if (lambda >= lambda_at(n - 1)) return value_at(n - 1);
    size_t hi = 1;
    while (lambda_at(hi) < lambda) ++hi;
    double t = (lambda - lambda_at(hi - 1)) / (lambda_at(hi) - lambda_at(hi - 1));
    return (1 - t) * value_at(hi - 1) + t * value_at(hi);
  };
  std::array<double, 3> rgb = XYZToLinearSRGB(IntegrateXYZ(eval));

  // The same normalisation serves every SpectrumType: dividing by the RGB of the flat
  // spectrum 1 maps a constant c to RGB(c, c, c) (see FlatSpectrumRGB). For illuminants this is
  // the "divide by the integral of y-bar, then white-balance E to D65" convention, so
  // "spectrum L" [ 360 1 830 1 ] emits like "rgb L" [ 1 1 1 ].
  (void)type;
  const std::array<double, 3>& white = FlatSpectrumRGB();
  return ToRGB({rgb[0] / white[0], rgb[1] / white[1], rgb[2] / white[2]});
}

std::optional<RGB> NamedSpectrumToRGB(const std::string& name) {
  struct Named {
    std::string_view name;
    RGB rgb;
  };
  static const Named kTable[] = {
      // Conductors: RGB projections of measured complex IORs (Palik's handbook data, as
      // tabulated for Mitsuba 0.5 and Tungsten's ComplexIorData, which pbrt-v4 scene
      // converters emit for the same metals). metal-Cu-* equals what the shared scenes use.
      {"metal-Cu-eta", {0.200438f, 0.924033f, 1.102212f}},
      {"metal-Cu-k", {3.912949f, 2.452848f, 2.142188f}},
      {"metal-Au-eta", {0.143119f, 0.374957f, 1.442479f}},
      {"metal-Au-k", {3.983160f, 2.385721f, 1.603215f}},
      {"metal-Ag-eta", {0.155265f, 0.116723f, 0.138381f}},
      {"metal-Ag-k", {4.828343f, 3.122246f, 2.146950f}},
      {"metal-Al-eta", {1.657460f, 0.880369f, 0.521229f}},
      {"metal-Al-k", {9.223869f, 6.269523f, 4.837001f}},
      // Brass (CuZn): the widely used RGB triple for pbrt-v4's metal-CuZn data.
      {"metal-CuZn-eta", {0.444f, 0.527f, 1.094f}},
      {"metal-CuZn-k", {3.695f, 2.765f, 1.829f}},
      // Glasses: refractive index at 550 nm, linearly interpolated from the refractiveindex.info
      // (CC0) Schott catalogue data that pbrt-v4 ships. A single grey value drops dispersion,
      // which an RGB renderer cannot show anyway. pbrt-v4's "glass-F5/F10/F11" are the SF5,
      // SF10 and SF11 glasses.
      {"glass-BK7", RGB(1.518537f)},
      {"glass-BAF10", RGB(1.673051f)},
      {"glass-FK51A", RGB(1.487796f)},
      {"glass-LASF9", RGB(1.855809f)},
      {"glass-F5", RGB(1.677089f)},
      {"glass-F10", RGB(1.733574f)},
      {"glass-F11", RGB(1.791119f)},
      // Standard illuminants: D65 is the film's white; A is by definition a 2856 K Planckian
      // radiator. Both are normalised to a maximum of 1 (lights scale them by "scale"/"power").
      {"stdillum-D65", RGB(1.f)},
  };
  for (const Named& n : kTable)
    if (n.name == name) return n.rgb;
  if (name == "stdillum-A") return BlackbodyToRGB(2856.f);
  return std::nullopt;
}

}  // namespace lightfarm
