#include "common/evaluation/clamp_probe.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <array>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "common/util/error.h"
#include "common/util/options.h"
#include "common/util/rng.h"

namespace lightfarm {
namespace {

// Lights the geometry clamp applies to that sit at a point (VRLs are clamped along their length,
// directional lights have no distance).
bool IsPointClamped(const VirtualLight& L) {
  return L.IsClamped() && !L.IsRay() && !L.IsDirectional();
}

// A uniform grid of cell size c over the lights' positions: the lights within c of a point are in
// the 27 cells around its own.
class NearGrid {
 public:
  NearGrid(const LightSet& lights, float cell) : inv_cell_(1.f / cell) {
    for (uint32_t j = 0; j < lights.size(); ++j)
      if (IsPointClamped(lights.lights[j])) cells_[Key(Cell(lights.lights[j].p))].push_back(j);
  }
  template <typename F>
  void ForNear(Vec3 p, F&& f) const {
    const std::array<int64_t, 3> c = Cell(p);
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(Key({c[0] + dx, c[1] + dy, c[2] + dz}));
          if (it != cells_.end())
            for (uint32_t j : it->second) f(j);
        }
  }

 private:
  std::array<int64_t, 3> Cell(Vec3 p) const {
    return {int64_t(std::floor(p.x * inv_cell_)), int64_t(std::floor(p.y * inv_cell_)),
            int64_t(std::floor(p.z * inv_cell_))};
  }
  static uint64_t Key(std::array<int64_t, 3> c) {
    return HashSeed({uint64_t(c[0]), uint64_t(c[1]), uint64_t(c[2])});
  }
  float inv_cell_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells_;
};

constexpr size_t kRowsPerChunk = 512;

}  // namespace

ClampLossProbe ProbeClampLoss(const Scene& scene, const ReceiverSet& receivers,
                              const LightGenerationOptions& light_options,
                              const MatrixOptions& matrix_options, int batches) {
  ClampLossProbe probe;
  if (batches <= 0 || matrix_options.clamp <= 0) return probe;
  // The matrix the render evaluates, without what it adds beyond its columns.
  MatrixOptions mopt = matrix_options;
  mopt.compensation_samples = 0;
  mopt.caustic_photons = 0;
  std::vector<double> losses;
  for (int b = 0; b < batches; ++b) {
    LightGenerationOptions lopt = light_options;
    lopt.seed = HashSeed({uint64_t(RngStream::kClampProbe), light_options.seed, uint64_t(b)});
    const LightSet lights = GenerateLights(scene, lopt);
    const LightingMatrix matrix(scene, receivers, lights, mopt);
    probe.bound_binds = matrix.bound_binds();
    const float c = matrix.clamp_distance();
    const float c2 = c * c;
    const NearGrid grid(lights, c);
    const size_t rows = matrix.point_rows();
    const size_t chunks = (rows + kRowsPerChunk - 1) / kRowsPerChunk;
    std::vector<MatrixCounters> counters(chunks);
    std::vector<size_t> pairs(chunks, 0);
    tbb::parallel_for(size_t(0), chunks, [&](size_t k) {
      std::vector<uint32_t> rs, cs;
      for (size_t r = k * kRowsPerChunk; r < std::min(rows, (k + 1) * kRowsPerChunk); ++r) {
        const Vec3 p = receivers.points[r].p;
        grid.ForNear(p, [&](uint32_t j) {
          const Vec3 d = lights.lights[j].p - p;
          if (Dot(d, d) < c2) {
            rs.push_back(uint32_t(r));
            cs.push_back(j);
          }
        });
      }
      std::vector<RGB> out(rs.size());
      matrix.EvaluateEntries(rs, cs, out, &counters[k]);
      pairs[k] = rs.size();
    });
    // Summed in chunk order: the same bits whatever the thread count.
    double lost = 0;
    for (size_t k = 0; k < chunks; ++k) {
      lost += counters[k].clamp_lost - counters[k].bound_lost;
      probe.pairs += pairs[k];
    }
    losses.push_back(lost);
  }
  probe.batches = batches;
  double sum = 0;
  for (double l : losses) sum += l;
  probe.mean = sum / double(batches);
  if (sum > 0) probe.largest_share = *std::max_element(losses.begin(), losses.end()) / sum;
  if (batches > 1) {
    double var = 0;
    for (double l : losses) var += (l - probe.mean) * (l - probe.mean);
    probe.stderr_ = std::sqrt(var / double(batches - 1) / double(batches));
  }
  return probe;
}

int TakeClampProbe(RenderSettings* settings) {
  const std::string key = "clamp_probe";
  int batches = 0;
  std::vector<std::string> rest;
  for (const std::string& entry : settings->params) {
    if (entry.rfind(key + "=", 0) != 0) {
      rest.push_back(entry);
      continue;
    }
    batches = int(OptionMap::Parse({entry}).GetInt(key, 0, 0, 100000));
  }
  settings->params = std::move(rest);
  return batches;
}

void AddClampProbe(const std::string& scene_path, const RenderSettings& settings, int batches,
                   nlohmann::json* stats) {
  nlohmann::json& clamp = (*stats)["clamp"];
  const double denom = clamp.value("unclamped_luminance", 0.0);
  if (batches <= 0 || denom <= 0) return;
  const auto t0 = std::chrono::steady_clock::now();
  const Plan plan = BuildPlan(scene_path, settings, nullptr);
  if (plan.method->renders_film()) return;
  const ClampLossProbe probe = ProbeClampLoss(*plan.scene, *plan.receivers, plan.light_options,
                                              plan.matrix_options, batches);
  const double compensated = plan.matrix->compensates() ? clamp.value("compensated_fraction", 0.0) : 0.0;
  // The element bound also binds beyond c, where the probe does not look: its part is the
  // render's own measure (zero where no material can reach the bound, as on a Lambertian scene).
  const double expected = probe.mean / denom + clamp.value("bound_lost_fraction", 0.0);
  clamp["probe"] = {{"light_sets", probe.batches},
                    {"pairs", probe.pairs},
                    {"bound_binds", probe.bound_binds},
                    {"expected_loss_fraction", expected},
                    {"expected_loss_stderr", probe.stderr_ / denom},
                    {"largest_light_set_share", probe.largest_share},
                    {"expected_loss_after_compensation", expected - compensated},
                    {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}};
}

}  // namespace lightfarm
