#include "common/render/progressive.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/util/rng.h"

namespace lightfarm {

namespace {

constexpr uint32_t kMagic = 0x3150464C;  // "LFP1"
constexpr uint16_t kVersion = 1;

// Relative standard error of a mean from its samples' mean and Σ (x − mean)²; 0 for a mean of
// exactly nothing (a black pixel stays black), infinite for noise around a zero mean.
double RelStderr(double mean, double m2, uint32_t n) {
  if (n < 2) return std::numeric_limits<double>::infinity();
  const double stderr_ = std::sqrt(m2 / double(n - 1) / double(n));
  if (mean > 0) return stderr_ / mean;
  return stderr_ == 0 ? 0 : std::numeric_limits<double>::infinity();
}

}  // namespace

uint64_t PassSeed(uint64_t seed, uint32_t pass) {
  return pass == 0 ? seed : HashSeed({seed, 0x70617373ull /* "pass" */, pass});
}

void PassAccumulator::Add(const Image& image, double seconds) {
  if (passes() == 0) {
    width_ = image.width;
    height_ = image.height;
    sum_.assign(image.PixelCount() * 3, 0.0);
    lum_mean_.assign(image.PixelCount(), 0.0);
    lum_m2_.assign(image.PixelCount(), 0.0);
  } else if (image.width != width_ || image.height != height_) {
    throw std::invalid_argument("pass " + std::to_string(passes()) + " is " + std::to_string(image.width) + "x" +
                                std::to_string(image.height) + ", the earlier passes " + std::to_string(width_) +
                                "x" + std::to_string(height_));
  }
  const double n = double(passes() + 1);
  for (size_t i = 0; i < image.PixelCount(); ++i) {
    const RGB& c = image.pixels[i];
    for (int k = 0; k < 3; ++k) sum_[3 * i + size_t(k)] += double(c[k]);
    // Welford (1962): stable where Σx² − (Σx)²/N cancels.
    const double x = double(c.Luminance());
    const double delta = x - lum_mean_[i];
    lum_mean_[i] += delta / n;
    lum_m2_[i] += delta * (x - lum_mean_[i]);
  }
  pass_means_.push_back(image.MeanLuminance());
  pass_seconds_.push_back(seconds);
}

Image PassAccumulator::Mean() const {
  Image out(width_, height_);
  const double n = double(std::max<uint32_t>(1, passes()));
  for (size_t i = 0; i < out.PixelCount(); ++i)
    for (int k = 0; k < 3; ++k) out.pixels[i][k] = float(sum_[3 * i + size_t(k)] / n);
  return out;
}

NoiseEstimate PassAccumulator::Noise() const {
  NoiseEstimate e;
  const uint32_t n = passes();
  if (n < 2) return e;
  double mean = 0, m2 = 0;
  for (uint32_t k = 0; k < n; ++k) {
    const double delta = pass_means_[k] - mean;
    mean += delta / double(k + 1);
    m2 += delta * (pass_means_[k] - mean);
  }
  e.rel_stderr = RelStderr(mean, m2, n);
  std::vector<double> rel;
  rel.reserve(lum_mean_.size());
  for (size_t i = 0; i < lum_mean_.size(); ++i)
    if (lum_mean_[i] > 0) rel.push_back(RelStderr(lum_mean_[i], lum_m2_[i], n));
  if (rel.empty()) {
    e.p90_rel_stderr = 0;
  } else {
    const size_t at = size_t(0.9 * double(rel.size() - 1));
    std::nth_element(rel.begin(), rel.begin() + std::ptrdiff_t(at), rel.end());
    e.p90_rel_stderr = rel[at];
  }
  return e;
}

uint32_t PassesToReach(const NoiseEstimate& estimate, uint32_t passes, double target) {
  const double noise = estimate.worst();
  if (!(target > 0) || !std::isfinite(noise)) return std::numeric_limits<uint32_t>::max();
  if (noise <= target) return 0;
  const double needed = std::ceil(double(passes) * (noise / target) * (noise / target));
  return uint32_t(std::min(needed - double(passes), 4e9));
}

Bytes PassAccumulator::Serialize() const {
  ByteWriter w;
  w.U32(kMagic);
  w.U16(kVersion);
  w.U32(uint32_t(width_));
  w.U32(uint32_t(height_));
  w.U64(passes());
  for (uint32_t k = 0; k < passes(); ++k) {
    w.F64(pass_means_[k]);
    w.F64(pass_seconds_[k]);
  }
  if (passes() > 0) {
    for (double v : sum_) w.F64(v);
    for (size_t i = 0; i < lum_mean_.size(); ++i) {
      w.F64(lum_mean_[i]);
      w.F64(lum_m2_[i]);
    }
  }
  return w.Take();
}

PassAccumulator PassAccumulator::Deserialize(ByteView bytes) {
  ByteReader r(bytes);
  if (r.U32() != kMagic) throw SerializeError("not a pass accumulation");
  if (const uint16_t v = r.U16(); v != kVersion)
    throw SerializeError("pass accumulation version " + std::to_string(v) + ", expected " + std::to_string(kVersion));
  PassAccumulator a;
  a.width_ = int(r.U32());
  a.height_ = int(r.U32());
  const size_t n = r.Count(16);
  for (size_t k = 0; k < n; ++k) {
    a.pass_means_.push_back(r.F64());
    a.pass_seconds_.push_back(r.F64());
  }
  if (n > 0) {
    if (a.width_ <= 0 || a.height_ <= 0 || uint64_t(a.width_) * uint64_t(a.height_) * 40 != r.remaining())
      throw SerializeError("pass accumulation: the pixels do not match its size");
    const size_t pixels = size_t(a.width_) * size_t(a.height_);
    a.sum_.resize(pixels * 3);
    for (double& v : a.sum_) v = r.F64();
    a.lum_mean_.resize(pixels);
    a.lum_m2_.resize(pixels);
    for (size_t i = 0; i < pixels; ++i) {
      a.lum_mean_[i] = r.F64();
      a.lum_m2_[i] = r.F64();
    }
  }
  r.ExpectEnd();
  return a;
}

bool WantsAnotherPass(const PassPlan& plan, const PassAccumulator& acc, double elapsed_s) {
  if (acc.passes() >= plan.passes) return false;
  if (plan.time_limit_s > 0 && elapsed_s >= plan.time_limit_s) return false;
  if (plan.until_noise > 0 && acc.passes() >= PassPlan::kMinNoisePasses && acc.Noise().worst() < plan.until_noise)
    return false;
  return true;
}

}  // namespace lightfarm
