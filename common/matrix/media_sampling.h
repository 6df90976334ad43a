// The sampling strategies media elements combine (segment_element.cpp, vrl_element.cpp): where the
// medium scatters (MediumTrack) and where the geometry term peaks (equi-angular towards a point,
// Kulla & Fajardo 2012; inverse distance to a line, Novák et al. 2012), mixed by the balance
// heuristic (Veach 1997, Sec. 9.2.2).
#pragma once

#include <algorithm>
#include <cmath>

#include "common/util/math.h"
#include "common/util/rng.h"

namespace lightfarm {

// Equi-angular sampling of a parameter on [0, len] of the line o + s·d (d unit) towards the
// point c: pdf ∝ 1/(D² + (s − Δ)²), uniform in the angle the line subtends at c.
struct EquiAngular {
  float delta = 0, dist = 0, theta_a = 0, theta_b = 0, len = 0;
  EquiAngular(Vec3 o, Vec3 d, float length, Vec3 c) : len(length) {
    delta = Dot(c - o, d);
    dist = std::max(Length(c - (o + d * delta)), 1e-7f);
    theta_a = std::atan2(-delta, dist);
    theta_b = std::atan2(len - delta, dist);
  }
  bool Valid() const { return theta_b > theta_a; }
  float Sample(float u) const { return Clamp(delta + dist * std::tan(theta_a + u * (theta_b - theta_a)), 0.f, len); }
  float Pdf(float s) const {
    if (!(s >= 0) || !(s <= len)) return 0.f;
    return dist / ((theta_b - theta_a) * (dist * dist + Sqr(s - delta)));
  }
};

// Novák 2012's VRL sampling: s on [0, len] of the line b + s·ψ with pdf ∝ 1/h(s), h(s) the
// distance from the point to the (infinite) eye-ray line a + t·ω:
//   h(s)² = h0² + sin²θ (s − s0)²   (θ the angle between the lines, s0 the closest point),
// whose CDF is an asinh. h0 is floored so the pdf stays finite for intersecting lines (still a
// normalised pdf, just not exactly ∝ 1/h); near-parallel lines sample s uniformly.
struct InverseDistance {
  float s0 = 0, h0 = 0, sin_t = 0, a = 0, b = 0, len = 0;
  bool uniform = false;
  InverseDistance(Vec3 vrl_o, Vec3 vrl_d, float vrl_len, Vec3 eye_o, Vec3 eye_d, float h_floor) {
    len = vrl_len;
    auto perp = [&](Vec3 v) { return v - eye_d * Dot(v, eye_d); };
    Vec3 pw = perp(vrl_o - eye_o), pd = perp(vrl_d);
    float sin2 = LengthSquared(pd);
    if (!(sin2 > 1e-6f)) {
      uniform = true;
      return;
    }
    sin_t = std::sqrt(sin2);
    s0 = -Dot(pw, pd) / sin2;
    h0 = std::max(SafeSqrt(LengthSquared(pw) - Sqr(Dot(pw, pd)) / sin2), h_floor);
    a = std::asinh((0 - s0) * sin_t / h0);
    b = std::asinh((len - s0) * sin_t / h0);
    if (!(b > a)) uniform = true;
  }
  float Sample(float u) const {
    if (uniform) return u * len;
    return Clamp(s0 + h0 / sin_t * std::sinh(a + u * (b - a)), 0.f, len);
  }
  float Pdf(float s) const {
    if (!(s >= 0) || !(s <= len)) return 0.f;
    if (uniform) return 1.f / len;
    return sin_t / ((b - a) * std::sqrt(h0 * h0 + Sqr(sin_t * (s - s0))));
  }
};

// n samples shared by two strategies, a fraction `alpha` of them by the first (the density). When
// α·n is a whole number the counts are fixed and each strategy's samples take their own strata;
// otherwise each sample picks its strategy at random with probability α. Either way the balance
// heuristic with the expected counts, f / (n α p_a + n (1 − α) p_b), is unbiased.
struct StrategyMix {
  int n = 1;
  float alpha = 0.5f;
  int split = -1;  // samples [0, split) use the first strategy, or -1: chosen at random
  StrategyMix(int samples, float a) : n(std::max(samples, 1)), alpha(Clamp(a, 0.f, 1.f)) {
    const float na = alpha * float(n);
    if (na == std::floor(na)) split = int(na);
  }
  // Whether sample k uses the first strategy, and u ∈ [0, 1) stratified within its strategy.
  bool First(int k, Rng& rng, float* u) const {
    if (split < 0) {
      *u = rng.Uniform();
      return rng.Uniform() < alpha;
    }
    const bool first = k < split;
    const int stratum = first ? k : k - split, strata = first ? split : n - split;
    *u = std::min((float(stratum) + rng.Uniform()) / float(strata), 0x1.fffffep-1f);
    return first;
  }
  // The factor that turns f(x) into the sample's contribution: 1 / (Σ_s count_s · p_s(x)).
  float Weight(float pdf_first, float pdf_second) const {
    const float denom = float(n) * (alpha * pdf_first + (1.f - alpha) * pdf_second);
    return denom > 0 && std::isfinite(denom) ? 1.f / denom : 0.f;
  }
};

}  // namespace lightfarm
