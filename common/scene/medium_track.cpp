#include "common/scene/medium_track.h"

#include <algorithm>
#include <cmath>

namespace lightfarm {

namespace {

// A grid cell whose optical depth along the ray exceeds this is split into up to
// kMaxSubdivision intervals (MediumTrack's constructor).
constexpr float kMaxIntervalDepth = 0.05f;
constexpr int kMaxSubdivision = 16;

// ∫_0^t σ_s e^{-σ_t x} dx for one channel.
float ChannelCdf(float sigma_s, float sigma_t, float t) {
  if (!(sigma_s > 0)) return 0.f;
  return sigma_t > 0 ? sigma_s * float(-std::expm1(double(-sigma_t) * double(t))) / sigma_t : sigma_s * t;
}

// The t with ChannelCdf(t) = c·ChannelCdf(ℓ) for one channel (an exponential truncated to [0, ℓ]).
float ChannelQuantile(float sigma_t, float len, float q) {
  if (!(sigma_t > 0)) return q * len;
  const double norm = -std::expm1(-double(sigma_t) * double(len));
  return Clamp(float(-std::log1p(-double(q) * norm) / double(sigma_t)), 0.f, len);
}

}  // namespace

MediumTrack::MediumTrack(const Medium& medium, const MediumRay& ray)
    : medium_(&medium), o_(ray.o), d_(ray.d), length_(std::max(ray.tmax, 0.f)),
      homogeneous_(medium.homogeneous()), sigma_s_(medium.sigma_s()), sigma_t_(medium.sigma_t()) {
  if (!(length_ > 0) || !std::isfinite(length_)) {
    length_ = std::isfinite(length_) ? length_ : 0.f;
    return;
  }
  if (homogeneous_) {
    weight_ = HomogeneousCdf(length_);
    return;
  }
  auto density = [&](float t) { return medium.Density(o_ + d_ * t); };
  const float sigma_t_avg = sigma_t_.Average();
  // Knots at the cell faces; an interval over empty space joins the empty one before it.
  bool last_empty = false;
  medium.ForEachDensityCell(ray, [&](float t0, float t1, bool empty) {
    if (knots_.empty()) {
      if (empty) return;  // leading empty space is outside the support
      knots_.push_back({t0, 0.f, density(t0), 0.f});
    }
    const Knot& prev = knots_.back();
    float inc = 0, d1 = 0;
    if (!empty) {
      d1 = density(t1);
      inc = (t1 - t0) * (1.f / 6.f) * (prev.density + 4.f * density(0.5f * (t0 + t1)) + d1);
    }
    const bool zero = !(inc > 0);
    if (zero && last_empty && knots_.size() >= 2) {
      knots_.back().t = t1;
      knots_.back().density = d1;
    } else if (const int m = std::min(kMaxSubdivision, int(std::ceil(sigma_t_avg * inc / kMaxIntervalDepth))); m > 1) {
      // An optically thick cell (a coarse grid): sub-intervals, each still one cubic for
      // Simpson, so that sampling inside follows Tr's decay.
      const float h = (t1 - t0) / float(m);
      for (int i = 1; i <= m; ++i) {
        const Knot& p = knots_.back();
        const float a = t0 + h * float(i - 1), b = i == m ? t1 : t0 + h * float(i);
        const float db = i == m ? d1 : density(b);
        knots_.push_back({b, p.depth + (b - a) * (1.f / 6.f) * (p.density + 4.f * density(0.5f * (a + b)) + db), db, 0.f});
      }
    } else {
      knots_.push_back({t1, prev.depth + inc, d1, 0.f});
    }
    last_empty = zero;
  });
  // Trailing empty space is outside the support too.
  while (knots_.size() >= 2 && !(knots_.back().depth > knots_[knots_.size() - 2].depth)) knots_.pop_back();
  if (knots_.size() < 2) {
    knots_.clear();
    return;
  }
  // Interval weights: ∫ σ_s,c·density·Tr_c dt = σ_s,c/σ_t,c · (Tr_c(t_k) − Tr_c(t_{k+1})) exactly,
  // whatever the density profile inside.
  RGB tr_prev = TransmittanceAtDepth(0.f);
  for (size_t k = 1; k < knots_.size(); ++k) {
    const RGB tr = TransmittanceAtDepth(knots_[k].depth);
    const float inc = knots_[k].depth - knots_[k - 1].depth;
    float w = 0;
    for (int c = 0; c < 3; ++c)
      w += sigma_t_[c] > 0 ? sigma_s_[c] / sigma_t_[c] * (tr_prev[c] - tr[c]) : sigma_s_[c] * inc;
    knots_[k].cdf = knots_[k - 1].cdf + std::max(w, 0.f) * (1.f / 3.f);
    tr_prev = tr;
  }
  weight_ = knots_.back().cdf;
  sigma_t_avg_ = sigma_t_.Average();
  // The matrix keeps a track per eye-segment piece and per VRL piece for the whole render: no
  // spare capacity from the appends (it was about half the knots' memory).
  knots_.shrink_to_fit();
}

RGB MediumTrack::TransmittanceAtDepth(float depth) const {
  RGB tr;
  for (int c = 0; c < 3; ++c) tr[c] = sigma_t_[c] > 0 ? std::exp(-sigma_t_[c] * depth) : 1.f;
  return tr;
}

float MediumTrack::HomogeneousCdf(float t) const {
  float sum = 0;
  for (int c = 0; c < 3; ++c) sum += ChannelCdf(sigma_s_[c], sigma_t_[c], t);
  return sum * (1.f / 3.f);
}

size_t MediumTrack::Locate(float t) const {
  if (homogeneous_ || knots_.empty() || !(t >= knots_.front().t) || !(t < knots_.back().t)) return kOutside;
  auto it = std::upper_bound(knots_.begin(), knots_.end(), t, [](float v, const Knot& k) { return v < k.t; });
  return std::clamp<size_t>(size_t(it - knots_.begin()), 1, knots_.size() - 1) - 1;
}

MediumTrack::Point MediumTrack::At(float t, size_t k) const {
  if (homogeneous_) {
    if (!(t >= 0) || !(t <= length_)) return {RGB(0.f), TransmittanceAtDepth(Clamp(t, 0.f, length_))};
    return {sigma_s_, TransmittanceAtDepth(t)};
  }
  if (k == kOutside) {
    if (knots_.empty() || !(t >= knots_.front().t)) return {RGB(0.f), RGB(1.f)};
    return {RGB(0.f), TransmittanceAtDepth(knots_.back().depth)};
  }
  const Knot& a = knots_[k];
  if (!(knots_[k + 1].depth > a.depth)) return {RGB(0.f), TransmittanceAtDepth(a.depth)};
  // The partial cell [t_k, t] by Simpson's rule (exact: a cubic).
  const float dt = medium_->Density(o_ + d_ * t);
  const float dm = medium_->Density(o_ + d_ * (0.5f * (a.t + t)));
  const float depth = a.depth + (t - a.t) * (1.f / 6.f) * (a.density + 4.f * dm + dt);
  return {sigma_s_ * dt, TransmittanceAtDepth(depth)};
}

RGB MediumTrack::TransmittanceToEnd() const {
  if (homogeneous_) return TransmittanceAtDepth(length_);
  return knots_.empty() ? RGB(1.f) : TransmittanceAtDepth(knots_.back().depth);
}

float MediumTrack::Pdf(float t, size_t k) const {
  if (!(weight_ > 0)) return 0.f;
  if (homogeneous_) {
    if (!(t >= 0) || !(t <= length_)) return 0.f;
    float w = 0;
    for (int c = 0; c < 3; ++c) w += sigma_s_[c] * (sigma_t_[c] > 0 ? std::exp(-sigma_t_[c] * t) : 1.f);
    return w * (1.f / 3.f) / weight_;
  }
  if (k == kOutside) return 0.f;
  const Knot &a = knots_[k], &b = knots_[k + 1];
  const float w = b.cdf - a.cdf, dt = b.t - a.t;
  if (!(dt > 0) || !(w > 0)) return 0.f;
  const float rate = IntervalRate(k);
  if (!(rate * dt > 1e-4f)) return w / (weight_ * dt);
  return w / weight_ * rate * std::exp(-rate * (t - a.t)) / float(-std::expm1(double(-rate * dt)));
}

float MediumTrack::IntervalRate(size_t k) const {
  return sigma_t_avg_ * (knots_[k + 1].depth - knots_[k].depth) / (knots_[k + 1].t - knots_[k].t);
}

float MediumTrack::Quantile(float q) const {
  q = Clamp(q, 0.f, 1.f);
  if (!(weight_ > 0)) return q * length_;
  if (homogeneous_) {
    const bool grey = sigma_t_[0] == sigma_t_[1] && sigma_t_[1] == sigma_t_[2];
    if (grey) return ChannelQuantile(sigma_t_[0], length_, q);
    // A mixture of exponentials: bisection on the cdf (cuts only, not a hot path).
    float lo = 0, hi = length_;
    const float target = q * weight_;
    for (int i = 0; i < 48; ++i) {
      const float mid = 0.5f * (lo + hi);
      (HomogeneousCdf(mid) < target ? lo : hi) = mid;
    }
    return 0.5f * (lo + hi);
  }
  return GridQuantile(q, nullptr);
}

float MediumTrack::GridQuantile(float q, size_t* where) const {
  const float target = q * weight_;
  auto it = std::upper_bound(knots_.begin(), knots_.end(), target, [](float v, const Knot& k) { return v < k.cdf; });
  size_t k = std::clamp<size_t>(size_t(it - knots_.begin()), 1, knots_.size() - 1) - 1;
  // Skip zero-weight intervals the search may land before (target exactly on their cdf).
  while (k + 2 < knots_.size() && !(knots_[k + 1].cdf > knots_[k].cdf)) ++k;
  const Knot &a = knots_[k], &b = knots_[k + 1];
  const float w = b.cdf - a.cdf, dt = b.t - a.t;
  const float f = w > 0 ? Clamp((target - a.cdf) / w, 0.f, 1.f) : 0.f;
  if (where) *where = k;
  // Inside the interval: the exponential of its mean extinction (uniform where that is flat).
  const float rate = IntervalRate(k);
  const float x = rate * dt > 1e-4f ? float(-std::log1p(double(f) * std::expm1(double(-rate * dt))) / double(rate))
                                    : f * dt;
  return std::min(a.t + Clamp(x, 0.f, dt), std::nextafter(b.t, a.t));
}

float MediumTrack::Sample(float u, float* pdf, size_t* where) const {
  size_t k = kOutside;
  float t = 0;
  if (!(weight_ > 0)) {
    *pdf = 0;
  } else if (homogeneous_) {
    // Choose a channel in proportion to its weight, then its truncated exponential; the pdf is
    // the mixture's, w(t)/W, whichever channel drew t.
    float cw[3], total = 0;
    for (int c = 0; c < 3; ++c) total += cw[c] = ChannelCdf(sigma_s_[c], sigma_t_[c], length_);
    float x = u * total;
    int c = 0;
    while (c < 2 && !(x < cw[c])) x -= cw[c++];
    while (c > 0 && !(cw[c] > 0)) --c;
    const float uc = cw[c] > 0 ? Clamp(x / cw[c], 0.f, 0x1.fffffep-1f) : u;
    t = ChannelQuantile(sigma_t_[c], length_, uc);
    *pdf = Pdf(t, k);
  } else {
    t = GridQuantile(u, &k);
    *pdf = Pdf(t, k);
  }
  if (where) *where = k;
  return t;
}

}  // namespace lightfarm
