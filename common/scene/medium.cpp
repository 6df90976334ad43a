#include "common/scene/medium.h"

#include <nanovdb/util/IO.h>

#include <cmath>
#include <filesystem>

namespace lightfarm {

namespace {

// exp(-σ·t) per channel, with 0·∞ = 0 (an empty channel transmits fully along any ray).
RGB ExpAttenuation(RGB sigma, float t) {
  RGB out;
  for (int c = 0; c < 3; ++c) out[c] = sigma[c] > 0 ? std::exp(-sigma[c] * t) : 1.f;
  return out;
}

// Exponential step -ln(1-u)/σ; u < 1 so the log is finite (1 − u is exact for Rng::Uniform's
// 24-bit values, so logf(1 − u) is as exact as log1pf(−u), and cheaper).
float ExponentialStep(float u, float sigma) { return -std::log(1.f - u) / sigma; }

// An optical-depth budget -ln(1-u) for tracking across majorant cells: one draw per tentative
// collision, however many cells the ray crosses before it (exponential steps are memoryless).
float ExponentialDepth(float u) { return -std::log(1.f - u); }

// A heterogeneous estimator takes at most this many tentative collisions per call: with a
// majorant far above the real density (or t so large that steps fall below its ulp) the loop
// would otherwise run unbounded; stopping there leaves a bias far below the noise.
constexpr int kMaxTrackingSteps = 1 << 20;

}  // namespace

float DensityGrid::Lookup(Vec3 g) const {
  float fx = std::floor(g.x), fy = std::floor(g.y), fz = std::floor(g.z);
  int x = int(fx), y = int(fy), z = int(fz);
  float dx = g.x - fx, dy = g.y - fy, dz = g.z - fz;
  auto lerp = [](float t, float a, float b) { return a + t * (b - a); };
  float c00 = lerp(dx, At(x, y, z), At(x + 1, y, z));
  float c10 = lerp(dx, At(x, y + 1, z), At(x + 1, y + 1, z));
  float c01 = lerp(dx, At(x, y, z + 1), At(x + 1, y, z + 1));
  float c11 = lerp(dx, At(x, y + 1, z + 1), At(x + 1, y + 1, z + 1));
  return lerp(dz, lerp(dy, c00, c10), lerp(dy, c01, c11));
}

Medium Medium::Homogeneous(RGB sigma_a, RGB sigma_s, float g) {
  Medium m;
  m.sigma_a_ = sigma_a;
  m.sigma_s_ = sigma_s;
  m.g_ = g;
  m.max_density_ = 1.f;
  return m;
}

Medium Medium::Grid(RGB sigma_a, RGB sigma_s, float g, DensityGrid grid,
                    const Transform& grid_from_world, const Transform& world_from_grid) {
  Medium m;
  m.sigma_a_ = sigma_a;
  m.sigma_s_ = sigma_s;
  m.g_ = g;
  m.grid_from_world_ = Affine3::From(grid_from_world);
  // About kMajorantVoxels voxels per majorant cell along each axis, at least kMinMajorantRes and
  // at most kMaxMajorantRes cells: majorants close to the density make tracking take few null
  // collisions (a small grid gets cells finer than its voxels: one dense voxel must not raise the
  // majorant of its neighbours).
  const float extent[3] = {grid.domain_hi.x - grid.domain_lo.x, grid.domain_hi.y - grid.domain_lo.y,
                           grid.domain_hi.z - grid.domain_lo.z};
  for (int a = 0; a < 3; ++a) {
    m.majorant_res_[a] = std::clamp(int(std::ceil(extent[a] / float(kMajorantVoxels))), kMinMajorantRes, kMaxMajorantRes);
    m.cell_size_[a] = extent[a] / float(m.majorant_res_[a]);
  }
  const int rx = m.majorant_res_[0], ry = m.majorant_res_[1], rz = m.majorant_res_[2];
  // Majorant cell (i, j, k) covers grid coordinates [lo + i·w, lo + (i+1)·w]; trilinear
  // interpolation there reads samples floor(lo + i·w) .. floor(lo + (i+1)·w) + 1.
  m.majorant_.assign(size_t(rx) * size_t(ry) * size_t(rz), 0.f);
  int n[3] = {grid.nx, grid.ny, grid.nz};
  std::vector<int> lo[3], hi[3];
  for (int a = 0; a < 3; ++a)
    for (int i = 0; i < m.majorant_res_[a]; ++i) {
      float c0 = grid.domain_lo[a] + float(i) * m.cell_size_[a];
      float c1 = c0 + m.cell_size_[a];
      lo[a].push_back(std::max(0, int(std::floor(c0))));
      hi[a].push_back(std::min(n[a] - 1, int(std::floor(c1)) + 1));
    }
  for (int k = 0; k < rz; ++k)
    for (int j = 0; j < ry; ++j)
      for (int i = 0; i < rx; ++i) {
        float mx = 0;
        for (int z = lo[2][size_t(k)]; z <= hi[2][size_t(k)]; ++z)
          for (int y = lo[1][size_t(j)]; y <= hi[1][size_t(j)]; ++y)
            for (int x = lo[0][size_t(i)]; x <= hi[0][size_t(i)]; ++x) mx = std::max(mx, grid.At(x, y, z));
        m.majorant_[(size_t(k) * size_t(ry) + size_t(j)) * size_t(rx) + size_t(i)] = mx;
        m.max_density_ = std::max(m.max_density_, mx);
      }
  for (int c = 0; c < 8; ++c) {
    Vec3 corner{(c & 1) ? grid.domain_hi.x : grid.domain_lo.x,
                (c & 2) ? grid.domain_hi.y : grid.domain_lo.y,
                (c & 4) ? grid.domain_hi.z : grid.domain_lo.z};
    m.world_bounds_.Extend(world_from_grid.ApplyPoint(corner));
  }
  m.grid_ = std::make_shared<const DensityGrid>(std::move(grid));
  return m;
}

float Medium::Density(Vec3 p) const {
  if (!grid_) return 1.f;
  return grid_->Lookup(grid_from_world_.Point(p));
}

RGB Medium::Transmittance(const MediumRay& ray, Rng& rng) const {
  if (!grid_) return ExpAttenuation(sigma_t(), ray.tmax);
  const RGB st = sigma_t();
  const Vec3 og = grid_from_world_.Point(ray.o), dg = grid_from_world_.Vector(ray.d);
  RGB T(1.f);
  int steps = 0;
  // Ratio tracking (Novák et al. 2014): T = Π (1 - σ_t(x_i)/σ̄) over tentative collisions.
  float depth = ExponentialDepth(rng.Uniform());  // to the next tentative collision
  ForEachMajorant(ray, [&](float t0, float t1, float smaj) {
    if (!(smaj > 0)) return true;
    float t = t0;
    while (++steps < kMaxTrackingSteps) {
      if (!(depth < smaj * (t1 - t))) {
        depth -= smaj * (t1 - t);
        return true;
      }
      t += depth / smaj;
      depth = ExponentialDepth(rng.Uniform());
      float dens = grid_->Lookup(og + dg * t);
      for (int c = 0; c < 3; ++c) T[c] *= std::max(0.f, 1.f - dens * st[c] / smaj);
      // Russian roulette once the estimate is small (unbiased: survivors are reweighted).
      if (T.Max() < 0.05f) {
        if (rng.Uniform() < 0.75f) {
          T = RGB(0.f);
          return false;
        }
        T = T / 0.25f;
      }
      if (T.IsBlack()) return false;
    }
    return false;
  });
  return T;
}

FreePathSample Medium::SampleFreePath(const MediumRay& ray, Rng& rng) const {
  FreePathSample s;
  s.t = ray.tmax;
  const RGB st = sigma_t();
  const float smax = st.Max();
  if (!(smax > 0)) return s;
  if (!grid_) {
    // Closed form with the max-channel rate: weights T_c(t)/p(t) per channel; grey media get
    // albedo and 1. The exponent is capped: beyond e^60 the event has probability ~e^-60.
    float t = ExponentialStep(rng.Uniform(), smax);
    auto ratio = [&](float d) {
      RGB w;
      for (int c = 0; c < 3; ++c) w[c] = std::exp(std::min((smax - st[c]) * d, 60.f));
      return w;
    };
    if (t < ray.tmax) {
      s.scattered = true;
      s.t = t;
      s.weight = sigma_s() / smax * ratio(t);
    } else {
      s.weight = ratio(ray.tmax);
    }
    return s;
  }
  const Vec3 og = grid_from_world_.Point(ray.o), dg = grid_from_world_.Vector(ray.d);
  const RGB ss = sigma_s();
  int steps = 0;
  float depth = ExponentialDepth(rng.Uniform());  // to the next tentative collision
  ForEachMajorant(ray, [&](float t0, float t1, float smaj) {
    if (!(smaj > 0)) return true;
    float t = t0;
    while (++steps < kMaxTrackingSteps) {
      if (!(depth < smaj * (t1 - t))) {
        depth -= smaj * (t1 - t);
        return true;
      }
      t += depth / smaj;
      depth = ExponentialDepth(rng.Uniform());
      float dens = grid_->Lookup(og + dg * t);
      float real = dens * smax;  // max-channel σ_t at x
      if (rng.Uniform() * smaj < real) {
        s.scattered = true;
        s.t = t;
        s.weight *= ss / smax;  // σ_s,c(x) / max_c σ_t,c(x): density cancels
        return false;
      }
      float null_max = smaj - real;
      if (null_max > 0)
        for (int c = 0; c < 3; ++c) s.weight[c] *= (smaj - dens * st[c]) / null_max;
    }
    return false;
  });
  return s;
}

// ---- construction from the scene file ------------------------------------------------------

namespace {

Transform GridFromUniformBox(Vec3 p0, Vec3 p1, int nx, int ny, int nz) {
  // pbrt-v4 SampledGrid: sample coordinates (p - p0)/(p1 - p0) · n - 0.5.
  Transform::Matrix m{};
  int n[3] = {nx, ny, nz};
  for (int a = 0; a < 3; ++a) {
    double s = double(n[a]) / (double(p1[a]) - double(p0[a]));
    m[a][a] = s;
    m[a][3] = -double(p0[a]) * s - 0.5;
  }
  m[3][3] = 1;
  return Transform(m);
}

DensityGrid LoadNanoVDB(const std::string& path, const FileLoc& loc, Transform* grid_from_medium) {
  if (!std::filesystem::is_regular_file(path))
    throw SceneError(loc, "nanovdb medium: cannot open \"" + path + "\"");
  nanovdb::GridHandle<nanovdb::HostBuffer> handle;
  try {
    handle = nanovdb::io::readGrid<nanovdb::HostBuffer>(path, "density");
  } catch (const std::exception& e) {
    throw SceneError(loc, "nanovdb medium: cannot read \"" + path + "\": " + e.what());
  }
  const nanovdb::FloatGrid* grid = handle.grid<float>();
  if (!grid)
    throw SceneError(loc, "nanovdb medium: \"" + path + "\" has no float grid named \"density\"");
  auto bbox = grid->indexBBox();
  DensityGrid g;
  g.nx = bbox.max()[0] - bbox.min()[0] + 1;
  g.ny = bbox.max()[1] - bbox.min()[1] + 1;
  g.nz = bbox.max()[2] - bbox.min()[2] + 1;
  if (g.nx <= 0 || g.ny <= 0 || g.nz <= 0 || size_t(g.nx) * g.ny * g.nz > (size_t(1) << 30))
    throw SceneError(loc, "nanovdb medium: \"" + path + "\" has an empty or huge index box");
  g.values.resize(size_t(g.nx) * g.ny * g.nz);
  auto acc = grid->getAccessor();
  for (int z = 0; z < g.nz; ++z)
    for (int y = 0; y < g.ny; ++y)
      for (int x = 0; x < g.nx; ++x) {
        nanovdb::Coord c(bbox.min()[0] + x, bbox.min()[1] + y, bbox.min()[2] + z);
        float v = acc.getValue(c);
        if (!std::isfinite(v) || v < 0)
          throw SceneError(loc, "nanovdb medium: \"" + path + "\" has negative or non-finite density");
        g.values[(size_t(z) * g.ny + y) * g.nx + x] = v;
      }
  // Voxel values sit at integer index coordinates; the voxels span [min, max + 1] (pbrt-v4
  // clips rays to the grid's world box).
  g.domain_lo = {0, 0, 0};
  g.domain_hi = {float(g.nx), float(g.ny), float(g.nz)};
  // The grid's own index-from-world map (affine), shifted so that index bbox.min is 0.
  auto f = [&](double x, double y, double z) {
    return grid->worldToIndexF(nanovdb::Vec3d(x, y, z));
  };
  nanovdb::Vec3d o = f(0, 0, 0), ex = f(1, 0, 0), ey = f(0, 1, 0), ez = f(0, 0, 1);
  Transform::Matrix m{};
  for (int r = 0; r < 3; ++r) {
    m[r][0] = ex[r] - o[r];
    m[r][1] = ey[r] - o[r];
    m[r][2] = ez[r] - o[r];
    m[r][3] = o[r] - double(bbox.min()[r]);
  }
  m[3][3] = 1;
  *grid_from_medium = Transform(m);
  return g;
}

}  // namespace

Medium CreateMedium(const MediumDesc& desc, const SceneDescription& scene) {
  const ParamSet& ps = desc.params;
  const std::string what = "MakeNamedMedium \"" + desc.name + "\" (\"" + desc.type + "\")";
  float scale = ps.GetOneFloat("scale", 1.f);
  RGB sigma_a = ps.GetOneRGB("sigma_a", SpectrumType::kUnbounded).value_or(RGB(1.f));
  RGB sigma_s = ps.GetOneRGB("sigma_s", SpectrumType::kUnbounded).value_or(RGB(1.f));
  float g = ps.GetOneFloat("g", 0.f);
  if (!(std::abs(g) < 1.f))
    throw SceneError(ps.Has("g") ? ps.Find("g")->loc : desc.loc,
                     what + ": \"g\" must lie in (-1, 1)");
  // Henyey–Greenstein with |g| → 1 is a delta; sampling and evaluation stay accurate to 0.99.
  g = Clamp(g, -0.995f, 0.995f);
  if (!(scale >= 0) || !std::isfinite(scale))
    throw SceneError(desc.loc, what + ": \"scale\" must be finite and >= 0");
  sigma_a *= scale;
  sigma_s *= scale;
  for (int c = 0; c < 3; ++c)
    if (!(sigma_a[c] >= 0) || !(sigma_s[c] >= 0) || !std::isfinite(sigma_a[c]) ||
        !std::isfinite(sigma_s[c]))
      throw SceneError(desc.loc, what + ": sigma_a and sigma_s must be finite and >= 0");
  // Emission: only "none" is supported; a zero Le (or Lescale 0) is accepted.
  auto check_le = [&](bool has_le) {
    float le_scale = ps.GetOneFloat("Lescale", 1.f);
    if (!has_le) return;
    RGB le = ps.GetOneRGB("Le", SpectrumType::kIlluminant).value_or(RGB(0.f));
    if (!le.IsBlack() && le_scale != 0)
      throw SceneError(ps.Find("Le")->loc, what + ": emissive media are not supported");
  };

  auto world_from_medium = desc.world_from_medium;
  auto medium_from_world = world_from_medium.Inverse();
  if (!medium_from_world) throw SceneError(desc.loc, what + ": transform is singular");

  Medium m;
  if (desc.type == "homogeneous") {
    check_le(true);
    m = Medium::Homogeneous(sigma_a, sigma_s, g);
  } else if (desc.type == "uniformgrid") {
    check_le(true);
    int nx = ps.GetOneInt("nx", 1), ny = ps.GetOneInt("ny", 1), nz = ps.GetOneInt("nz", 1);
    if (nx < 1 || ny < 1 || nz < 1)
      throw SceneError(desc.loc, what + ": \"nx\", \"ny\", \"nz\" must be >= 1");
    std::vector<float> density = ps.GetFloatArray("density");
    if (density.size() != size_t(nx) * ny * nz)
      throw SceneError(ps.Has("density") ? ps.Find("density")->loc : desc.loc,
                       what + ": \"density\" has " + std::to_string(density.size()) +
                           " values, expected nx·ny·nz = " +
                           std::to_string(size_t(nx) * ny * nz));
    for (float v : density)
      if (!(v >= 0) || !std::isfinite(v))
        throw SceneError(ps.Find("density")->loc, what + ": \"density\" must be finite and >= 0");
    Vec3 p0 = ps.GetOnePoint3("p0").value_or(Vec3{0, 0, 0});
    Vec3 p1 = ps.GetOnePoint3("p1").value_or(Vec3{1, 1, 1});
    if (!(p0.x < p1.x && p0.y < p1.y && p0.z < p1.z))
      throw SceneError(desc.loc, what + ": need p0 < p1 on every axis");
    DensityGrid grid;
    grid.nx = nx;
    grid.ny = ny;
    grid.nz = nz;
    grid.values = std::move(density);
    grid.domain_lo = {-0.5f, -0.5f, -0.5f};
    grid.domain_hi = {float(nx) - 0.5f, float(ny) - 0.5f, float(nz) - 0.5f};
    Transform grid_from_medium = GridFromUniformBox(p0, p1, nx, ny, nz);
    Transform grid_from_world = grid_from_medium * *medium_from_world;
    m = Medium::Grid(sigma_a, sigma_s, g, std::move(grid), grid_from_world,
                     *grid_from_world.Inverse());
  } else if (desc.type == "nanovdb") {
    check_le(false);
    std::string file = ps.GetOneString("filename", "");
    if (file.empty()) throw SceneError(desc.loc, what + ": needs \"string filename\"");
    Transform grid_from_medium;
    DensityGrid grid =
        LoadNanoVDB(scene.ResolvePath(file), ps.Find("filename")->loc, &grid_from_medium);
    Transform grid_from_world = grid_from_medium * *medium_from_world;
    auto world_from_grid = grid_from_world.Inverse();
    if (!world_from_grid) throw SceneError(desc.loc, what + ": grid transform is singular");
    m = Medium::Grid(sigma_a, sigma_s, g, std::move(grid), grid_from_world, *world_from_grid);
  } else {
    throw SceneError(desc.loc, "unsupported medium type \"" + desc.type + "\" in MakeNamedMedium \"" +
                                   desc.name + "\" (supported: homogeneous, uniformgrid, nanovdb)");
  }
  ps.ReportUnused(what);
  m.set_name(desc.name);
  return m;
}

}  // namespace lightfarm
