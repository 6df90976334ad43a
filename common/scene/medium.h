// Participating media (pbrt-v4 MakeNamedMedium): homogeneous, "uniformgrid" (inline density
// grid) and "nanovdb" (a .nvdb file). A heterogeneous medium is σ_a(x) = density(x)·σ_a,
// σ_s(x) = density(x)·σ_s with a trilinearly interpolated density grid.
//
// Distances are world-space: a ray o + t·d with unit world d has σ_t(o + t·d) per world unit
// (the grid is looked up through the medium's transform; t is not rescaled by it). pbrt-v4
// measures t in medium space instead, which differs only for scaled medium transforms.
//
// RGB: free paths and ratio tracking use one scalar majorant per region, the largest channel
// of σ_t (σ̄ = max_c σ_t,c · max density of the region). Delta tracking then picks a real
// collision with probability max_c σ_t,c(x) / σ̄ and carries per-channel weights: σ_s,c/max σ_t
// at a scattering event, (σ̄ − σ_t,c)/(σ̄ − max σ_t) at a null event (spectral tracking, Kutz
// et al. 2017, "max" probabilities). Grey media get the weights albedo and 1 exactly. Ratio
// tracking multiplies per channel by (1 − σ_t,c(x)/σ̄), which never goes negative.
#pragma once

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "common/scene/scene_description.h"
#include "common/util/math.h"
#include "common/util/rng.h"
#include "common/util/transform.h"

namespace lightfarm {

// A ray segment through one medium: o + t·d, t ∈ [0, tmax], d unit (world space).
struct MediumRay {
  Vec3 o, d;
  float tmax = 0;
};

// Result of free-path sampling (delta tracking) along a MediumRay.
struct FreePathSample {
  bool scattered = false;  // a real collision at t < tmax; otherwise the ray left the segment
  float t = 0;             // collision distance (scattered) or tmax
  RGB weight{1.f};         // multiply the path throughput by this (see header comment)
};

// Density on a regular grid, trilinear between samples at integer "grid coordinates"; zero
// outside. grid_from_world maps world points to grid coordinates.
struct DensityGrid {
  int nx = 0, ny = 0, nz = 0;
  std::vector<float> values;  // x fastest
  Vec3 domain_lo, domain_hi;  // grid-coordinate box where the density may be non-zero
  float Lookup(Vec3 g) const;  // trilinear, g in grid coordinates
  float At(int x, int y, int z) const {
    if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) return 0.f;
    return values[(size_t(z) * ny + y) * nx + x];
  }
};

// A float affine map (the hot path of density lookups; Transform works in double).
struct Affine3 {
  float m[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
  static Affine3 From(const Transform& t) {
    Affine3 a;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) a.m[r][c] = float(t.m()[r][c]);
    return a;
  }
  Vec3 Point(Vec3 p) const {
    return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
            m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
            m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
  }
  Vec3 Vector(Vec3 v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
  }
};

class Medium {
 public:
  // A homogeneous medium with the given coefficients (scale already applied).
  static Medium Homogeneous(RGB sigma_a, RGB sigma_s, float g);
  // A heterogeneous medium: coefficients times the grid density; grid_from_world as above.
  static Medium Grid(RGB sigma_a, RGB sigma_s, float g, DensityGrid grid,
                     const Transform& grid_from_world, const Transform& world_from_grid);

  bool homogeneous() const { return !grid_; }
  float g() const { return g_; }
  RGB sigma_a() const { return sigma_a_; }  // per unit density
  RGB sigma_s() const { return sigma_s_; }
  RGB sigma_t() const { return sigma_a_ + sigma_s_; }
  const std::string& name() const { return name_; }
  void set_name(std::string n) { name_ = std::move(n); }

  // Density at a world point (1 for homogeneous media).
  float Density(Vec3 p) const;
  float MaxDensity() const { return grid_ ? max_density_ : 1.f; }
  // World-space bounds of where the density may be non-zero (empty box for homogeneous media).
  Bounds3 WorldBounds() const { return world_bounds_; }

  // Transmittance along the segment: closed form exp(-σ_t·t) if homogeneous, else ratio
  // tracking over the majorant grid (unbiased, per channel; Russian roulette once small).
  RGB Transmittance(const MediumRay& ray, Rng& rng) const;
  // Delta (Woodcock) tracking over the majorant grid; closed form for homogeneous media.
  FreePathSample SampleFreePath(const MediumRay& ray, Rng& rng) const;

  // Calls fn(t0, t1, sigma_maj) for consecutive pieces of [0, ray.tmax] in order (3D-DDA over
  // the coarse majorant grid; one piece for homogeneous media); stops when fn returns false.
  // sigma_maj is the scalar majorant max_c σ_t,c · max density over the piece.
  template <typename Fn>
  void ForEachMajorant(const MediumRay& ray, Fn&& fn) const;
  // Calls fn(t0, t1, empty) for consecutive pieces of [0, ray.tmax] inside the density's
  // domain, in order: a piece over an empty majorant cell whole (empty = true: the density is 0
  // on all of it), else one piece per grid cell the ray crosses, so that the density is one
  // trilinear polynomial on each (a cubic in t: Simpson's rule integrates it exactly). Grid
  // media only.
  template <typename Fn>
  void ForEachDensityCell(const MediumRay& ray, Fn&& fn) const;

  // The majorant grid: about this many density voxels per cell along each axis, between
  // kMinMajorantRes and kMaxMajorantRes cells.
  static constexpr int kMajorantVoxels = 8, kMinMajorantRes = 16, kMaxMajorantRes = 64;

 private:
  RGB sigma_a_, sigma_s_;
  float g_ = 0;
  std::string name_;
  std::shared_ptr<const DensityGrid> grid_;
  Affine3 grid_from_world_;
  std::vector<float> majorant_;  // max densities of majorant_res_ cells, x fastest
  int majorant_res_[3] = {1, 1, 1};
  Vec3 cell_size_;               // grid coordinates per majorant cell
  float max_density_ = 0;
  Bounds3 world_bounds_;
};

// Builds a medium from MakeNamedMedium; every parameter is read or reported with file:line.
Medium CreateMedium(const MediumDesc& desc, const SceneDescription& scene);

// ---- template implementation --------------------------------------------------------------

template <typename Fn>
void Medium::ForEachMajorant(const MediumRay& ray, Fn&& fn) const {
  if (!(ray.tmax > 0)) return;
  const float smax = sigma_t().Max();
  if (!grid_) {
    fn(0.f, ray.tmax, smax);
    return;
  }
  // Ray in grid coordinates; the parameter t is unchanged by the affine map.
  Vec3 o = grid_from_world_.Point(ray.o);
  Vec3 d = grid_from_world_.Vector(ray.d);
  const DensityGrid& g = *grid_;
  // Slab clip against the domain box.
  float t0 = 0, t1 = ray.tmax;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.f) {
      if (o[a] < g.domain_lo[a] || o[a] > g.domain_hi[a]) return;
      continue;
    }
    float inv = 1.f / d[a];
    float ta = (g.domain_lo[a] - o[a]) * inv, tb = (g.domain_hi[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (!(t0 < t1)) return;
  }
  // 3D-DDA over majorant cells (Amanatides & Woo 1987).
  int cell[3], step[3], limit[3];
  float next[3], delta[3];
  for (int a = 0; a < 3; ++a) {
    float pa = (o[a] + d[a] * t0 - g.domain_lo[a]) / cell_size_[a];
    cell[a] = Clamp(int(std::floor(pa)), 0, majorant_res_[a] - 1);
    if (d[a] > 0) {
      step[a] = 1;
      limit[a] = majorant_res_[a];
      float edge = g.domain_lo[a] + float(cell[a] + 1) * cell_size_[a];
      next[a] = t0 + (edge - (o[a] + d[a] * t0)) / d[a];
      delta[a] = cell_size_[a] / d[a];
    } else if (d[a] < 0) {
      step[a] = -1;
      limit[a] = -1;
      float edge = g.domain_lo[a] + float(cell[a]) * cell_size_[a];
      next[a] = t0 + (edge - (o[a] + d[a] * t0)) / d[a];
      delta[a] = -cell_size_[a] / d[a];
    } else {
      step[a] = 0;
      limit[a] = -2;
      next[a] = kInfinity;
      delta[a] = kInfinity;
    }
  }
  float t = t0;
  const int max_steps = majorant_res_[0] + majorant_res_[1] + majorant_res_[2] + 8;
  for (int guard = 0; guard < max_steps && t < t1; ++guard) {
    int axis = next[0] < next[1] ? (next[0] < next[2] ? 0 : 2) : (next[1] < next[2] ? 1 : 2);
    float tend = std::min(std::max(next[axis], t), t1);
    float dens = majorant_[(size_t(cell[2]) * size_t(majorant_res_[1]) + size_t(cell[1])) * size_t(majorant_res_[0]) +
                           size_t(cell[0])];
    if (tend > t && !fn(t, tend, dens * smax)) return;
    t = tend;
    cell[axis] += step[axis];
    if (cell[axis] == limit[axis]) return;
    next[axis] += delta[axis];
  }
}

template <typename Fn>
void Medium::ForEachDensityCell(const MediumRay& ray, Fn&& fn) const {
  if (!grid_) return;
  const Vec3 o = grid_from_world_.Point(ray.o), d = grid_from_world_.Vector(ray.d);
  ForEachMajorant(ray, [&](float t0, float t1, float smaj) {
    if (!(smaj > 0)) {
      fn(t0, t1, true);
      return true;
    }
    // The next integer face along each axis (grid coordinates), as an index so that every
    // crossing is computed afresh from (face - o)/d instead of accumulated.
    float face[3], inv[3];
    const Vec3 p0 = o + d * t0;
    for (int a = 0; a < 3; ++a) {
      if (d[a] > 0) {
        face[a] = std::floor(p0[a]) + 1.f;
        inv[a] = 1.f / d[a];
      } else if (d[a] < 0) {
        face[a] = std::ceil(p0[a]) - 1.f;
        inv[a] = 1.f / d[a];
      } else {
        face[a] = 0;
        inv[a] = 0;
      }
    }
    auto crossing = [&](int a) { return d[a] != 0.f ? (face[a] - o[a]) * inv[a] : kInfinity; };
    float t = t0;
    for (int guard = 0; guard < (1 << 16) && t < t1; ++guard) {
      float next = std::min({crossing(0), crossing(1), crossing(2), t1});
      if (next > t) {
        fn(t, next, false);
        t = next;
      }
      for (int a = 0; a < 3; ++a)
        if (d[a] != 0.f && crossing(a) <= t) face[a] += d[a] > 0 ? 1.f : -1.f;
    }
    return true;
  });
}

}  // namespace lightfarm
