// Where a ray piece inside one medium scatters light, tabulated once so that every matrix element
// on it samples there (docs/rendering.md, "Elements"). Along o + t·d, t ∈ [0, ℓ]:
//
//   w(t) = mean_c σ_s,c(t) · Tr_c(0→t),   W = ∫_0^ℓ w(t) dt
//
// (for a grey medium W = albedo × (1 − Tr(ℓ)), the probability that light entering the piece
// scatters in it). Eye segments and VRLs both are such pieces: an element samples its parameters
// ∝ w on each, and reads the transmittance to the sample from here instead of tracking it.
//
// Grid media: the density is trilinear in each grid cell, so along the ray it is a cubic in t
// there and Simpson's rule integrates it exactly. Knots sit where the ray crosses cell faces
// (runs of empty majorant cells are one interval), each holding the exact optical depth
// D(t_k) = ∫_0^{t_k} density dt; Tr(t) at any t is then exact with two density lookups (the
// partial cell by Simpson). Interval k has the exact weight mean_c σ_s,c/σ_t,c · (Tr_c(t_k) −
// Tr_c(t_{k+1})) and inside it t is drawn ∝ exp(−σ̄_k (t − t_k)), σ̄_k its mean extinction: the
// pdf is known exactly, so estimators that divide by it are unbiased, and their weight σ_s·Tr/pdf
// varies only as the density within one cell does.
// Homogeneous media: closed forms, no knots; w is sampled exactly (one exponential per channel,
// chosen in proportion to its weight).
#pragma once

#include <vector>

#include "common/scene/medium.h"

namespace lightfarm {

class MediumTrack {
 public:
  MediumTrack() = default;  // nothing scatters: W = 0
  MediumTrack(const Medium& medium, const MediumRay& ray);

  float length() const { return length_; }
  float weight() const { return weight_; }
  bool empty() const { return !(weight_ > 0); }
  // [begin, end] ⊆ [0, ℓ]: where the density may be non-zero (all of it in a homogeneous medium).
  float support_begin() const { return knots_.empty() ? 0.f : knots_.front().t; }
  float support_end() const { return knots_.empty() ? (homogeneous_ ? length_ : 0.f) : knots_.back().t; }
  // Knots held (memory and work measures; 0 for homogeneous media).
  size_t knots() const { return knots_.size(); }

  // σ_s and Tr(0→t) at o + t·d, both exact.
  struct Point {
    RGB sigma_s;
    RGB tr;
  };
  Point At(float t) const { return At(t, Locate(t)); }
  RGB TransmittanceToEnd() const;
  // t with density pdf(t) ∝ w(t) (piecewise, see above); u ∈ [0, 1). Stratified u gives strata
  // of equal weight. `where` (optional) receives Locate(t), for At and Pdf.
  float Sample(float u, float* pdf, size_t* where = nullptr) const;
  float Pdf(float t) const { return Pdf(t, Locate(t)); }
  // The knot interval holding t, found once for At and Pdf of the same t (a binary search).
  static constexpr size_t kOutside = ~size_t(0);
  size_t Locate(float t) const;
  Point At(float t, size_t where) const;
  float Pdf(float t, size_t where) const;
  // t with ∫_0^t w = q·W, for cuts into pieces of equal weight (q ∈ [0, 1]).
  float Quantile(float q) const;

 private:
  struct Knot {
    float t = 0;        // along the ray
    float depth = 0;    // ∫_0^t density (grid units of σ_t: optical depth_c = σ_t,c · depth)
    float density = 0;  // at t
    float cdf = 0;      // ∫_0^t w
  };
  RGB TransmittanceAtDepth(float depth) const;
  // Grid media: the quantile and the interval it lies in.
  float GridQuantile(float q, size_t* where) const;
  // Interval k's mean extinction (channel average): inside it, t is drawn ∝ exp(−rate·(t − t_k)).
  float IntervalRate(size_t k) const;
  // Homogeneous media: ∫_0^t w.
  float HomogeneousCdf(float t) const;

  const Medium* medium_ = nullptr;
  Vec3 o_, d_;
  float length_ = 0, weight_ = 0;
  bool homogeneous_ = false;
  RGB sigma_s_, sigma_t_;
  float sigma_t_avg_ = 0;
  std::vector<Knot> knots_;
};

}  // namespace lightfarm
