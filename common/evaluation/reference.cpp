#include "common/evaluation/reference.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <unordered_map>

#include "common/image/film.h"
#include "common/util/file.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

// Bump when the cached format or the meaning of the key changes.
constexpr uint64_t kReferenceFormat = 6;  // 2: subsets include eye-segment rows; 3: clamp compensation; 4: caustics; 5: sharp lobes; 6: element bound
// Files above this size (volume grids) are hashed by size and mtime, not content.
constexpr uintmax_t kContentHashLimit = uintmax_t(64) << 20;
// Stream id of the pixel-subset choice (outside RngStream's range: bench only).
constexpr uint64_t kPixelSubsetStream = 0xBE7C4;

std::atomic<uint64_t> g_computations{0};

class Fnv1a {
 public:
  void Bytes(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h_ = (h_ ^ p[i]) * 0x100000001b3ULL;
  }
  void String(const std::string& s) {
    U64(s.size());
    Bytes(s.data(), s.size());
  }
  void U64(uint64_t v) { Bytes(&v, sizeof v); }
  uint64_t value() const { return h_; }

 private:
  uint64_t h_ = 0xcbf29ce484222325ULL;
};

// The scene file and every file it names (a quoted string that is an existing path relative to
// the naming file: Include/Import, meshes, textures, volume grids), transitively through .pbrt
// files; never the rest of the directory, so outputs written beside a scene do not change it.
void HashSceneFiles(const std::string& scene, Fnv1a* h) {
  std::vector<fs::path> todo = {fs::absolute(scene).lexically_normal()};
  std::set<fs::path> seen(todo.begin(), todo.end());
  const fs::path root = todo.front().parent_path();
  std::vector<char> buf(1 << 16);
  for (size_t i = 0; i < todo.size(); ++i) {
    const fs::path f = todo[i];
    h->String(fs::relative(f, root).string());
    const uintmax_t size = fs::file_size(f);
    h->U64(size);
    if (size > kContentHashLimit) {
      h->U64(uint64_t(fs::last_write_time(f).time_since_epoch().count()));
      continue;
    }
    std::ifstream in(f, std::ios::binary);
    std::string text;
    while (in) {
      in.read(buf.data(), std::streamsize(buf.size()));
      h->Bytes(buf.data(), size_t(in.gcount()));
      if (f.extension() == ".pbrt") text.append(buf.data(), size_t(in.gcount()));
    }
    for (size_t q = text.find('"'); q != std::string::npos; q = text.find('"', q + 1)) {
      const size_t e = text.find('"', q + 1);
      if (e == std::string::npos) break;
      const std::string name = text.substr(q + 1, e - q - 1);
      q = e;
      if (name.empty() || name.size() > 4096 || name.find('\n') != std::string::npos) continue;
      std::error_code ec;
      const fs::path p = (f.parent_path() / name).lexically_normal();
      if (fs::is_regular_file(p, ec) && seen.insert(p).second) todo.push_back(p);
    }
  }
}

std::string CachePath(const ReferenceRequest& r, const std::string& key, const char* ext) {
  return (fs::path(r.cache_dir) / (key + ext)).string();
}

void SaveReference(const ReferenceRequest& r, const BenchReference& ref) {
  fs::create_directories(r.cache_dir);
  // Raw floats, not EXR: a cached reference must equal the computed one bit for bit.
  const std::string bin = CachePath(r, ref.key, ".bin");
  {
    const int32_t wh[2] = {ref.image.width, ref.image.height};
    std::string bytes(reinterpret_cast<const char*>(wh), sizeof wh);
    bytes.append(reinterpret_cast<const char*>(ref.image.pixels.data()), ref.image.pixels.size() * sizeof(RGB));
    WriteFileAtomically(bin, bytes);
  }
  nlohmann::json meta;
  meta["scene"] = fs::absolute(r.scene).string();
  meta["lights_requested"] = r.settings.lights;
  meta["lights"] = ref.lights;
  meta["resolution"] = {ref.image.width, ref.image.height};
  meta["spp"] = std::max(1, r.settings.spp);
  meta["seed"] = r.settings.seed;
  meta["params"] = r.settings.params;
  meta["pixels"] = ref.pixels;
  meta["brute_seconds"] = ref.brute_seconds;
  meta["brute_shadow_rays"] = ref.brute_shadow_rays;
  meta["brute_elements"] = ref.brute_elements;
  meta["extrapolated"] = ref.extrapolated;
  const std::string json = CachePath(r, ref.key, ".json");
  WriteFileAtomically(json, meta.dump(1) + "\n");
}

// Brute force on the receivers of the chosen pixels only; the film adds exactly the samples
// AssembleImage would add to those pixels, in the same order, so the values are identical.
BenchReference ComputeReference(const ReferenceRequest& r) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  RenderSettings s = r.settings;
  s.method = "brute";
  PhaseTimes times;
  Plan plan = BuildPlan(r.scene, s, &times);
  const int w = plan.receivers->width, h = plan.receivers->height;
  BenchReference ref;
  ref.lights = plan.lights->size();
  MatrixCounters counters;
  if (r.pixels == 0 || r.pixels >= size_t(w) * size_t(h)) {
    GatherOutcome outcome = RunStagesLocally(plan, nullptr, &times);
    ref.image = AssembleImage(plan, outcome, nullptr);
    ref.brute_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    ref.brute_shadow_rays = double(outcome.counters.shadow_rays);
    ref.brute_elements = double(outcome.counters.elements);
    g_computations++;
    return ref;
  }
  const auto t_gather = Clock::now();
  ref.pixels = ReferencePixelSubset(w, h, r.pixels, s.seed);
  std::vector<uint8_t> chosen(size_t(w) * size_t(h), 0);
  for (uint32_t p : ref.pixels) chosen[p] = 1;
  std::vector<uint32_t> rows;
  for (const CameraSample& cs : plan.receivers->samples)
    if (chosen[cs.pixel]) SampleRows(plan, cs, &rows);
  std::sort(rows.begin(), rows.end());
  rows.erase(std::unique(rows.begin(), rows.end()), rows.end());
  std::vector<RGBAccum> sums(plan.matrix->rows());
  std::vector<MatrixCounters> per_row(rows.size());
  tbb::parallel_for(size_t(0), rows.size(), [&](size_t i) {
    sums[rows[i]] = plan.matrix->RowSum(rows[i], &per_row[i]);
    // As RunGatherTask adds it to every final-stage row (compensation and caustics).
    sums[rows[i]].Add(plan.matrix->ExtraLight(rows[i], &per_row[i]));
  });
  for (const MatrixCounters& c : per_row) counters.Add(c);
  const double gather_seconds = std::chrono::duration<double>(Clock::now() - t_gather).count();
  Film film(w, h);
  for (const CameraSample& cs : plan.receivers->samples) {
    if (chosen[cs.pixel]) film.AddSample(int(cs.pixel), SampleRadiance(plan, cs, sums), cs.weight);
  }
  ref.image = film.Resolve();
  // Full brute force would evaluate every row: scale the gather's cost by rows / subset rows.
  const double scale = rows.empty() ? 0.0 : double(plan.matrix->rows()) / double(rows.size());
  double plan_seconds = 0;
  for (const auto& [name, secs] : times.phases) plan_seconds += secs;
  ref.brute_seconds = plan_seconds + gather_seconds * scale;
  ref.brute_shadow_rays = double(counters.shadow_rays) * scale;
  ref.brute_elements = double(plan.matrix->rows()) * double(plan.matrix->cols());
  ref.extrapolated = true;
  g_computations++;
  return ref;
}

}  // namespace

std::string ReferenceKey(const ReferenceRequest& r) {
  Fnv1a h;
  h.U64(kReferenceFormat);
  h.String(LIGHTFARM_VERSION);
  HashSceneFiles(r.scene, &h);
  const RenderSettings& s = r.settings;
  h.U64(uint64_t(s.width));
  h.U64(uint64_t(s.height));
  h.String(s.filter);
  h.U64(uint64_t(std::max(1, s.spp)));  // brute: 0 (the default) is 1 sample
  h.U64(s.lights);
  h.U64(s.seed);
  for (const std::string& p : s.params) h.String(p);
  h.U64(r.pixels);
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h.value()));
  return hex;
}

std::string SceneFilesHash(const std::string& scene) {
  Fnv1a h;
  HashSceneFiles(scene, &h);
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h.value()));
  return hex;
}

bool LoadCachedReference(const ReferenceRequest& r, BenchReference* out) {
  if (r.cache_dir.empty()) return false;
  const std::string key = ReferenceKey(r);
  const std::string bin = CachePath(r, key, ".bin"), json = CachePath(r, key, ".json");
  if (!fs::exists(bin) || !fs::exists(json)) return false;
  nlohmann::json meta = nlohmann::json::parse(std::ifstream(json));
  std::ifstream in(bin, std::ios::binary);
  int32_t wh[2] = {0, 0};
  in.read(reinterpret_cast<char*>(wh), sizeof wh);
  BenchReference ref;
  ref.image = Image(wh[0], wh[1]);
  in.read(reinterpret_cast<char*>(ref.image.pixels.data()),
          std::streamsize(ref.image.pixels.size() * sizeof(RGB)));
  if (!in) return false;  // truncated: recompute
  ref.key = key;
  ref.pixels = meta["pixels"].get<std::vector<uint32_t>>();
  ref.brute_seconds = meta["brute_seconds"].get<double>();
  ref.brute_shadow_rays = meta["brute_shadow_rays"].get<double>();
  ref.brute_elements = meta.value("brute_elements", 0.0);
  ref.extrapolated = meta["extrapolated"].get<bool>();
  ref.lights = meta["lights"].get<size_t>();
  ref.from_cache = true;
  *out = std::move(ref);
  return true;
}

BenchReference GetReference(const ReferenceRequest& r) {
  BenchReference ref;
  if (LoadCachedReference(r, &ref)) return ref;
  ref = ComputeReference(r);
  ref.key = ReferenceKey(r);
  if (!r.cache_dir.empty()) SaveReference(r, ref);
  return ref;
}

uint64_t ReferenceComputations() { return g_computations.load(); }

std::vector<uint32_t> ReferencePixelSubset(int width, int height, size_t count, uint64_t seed) {
  const uint32_t n = uint32_t(size_t(width) * size_t(height));
  count = std::min<size_t>(count, n);
  // Partial Fisher-Yates over a sparse map of swapped indices: O(count) memory.
  std::vector<uint32_t> out;
  out.reserve(count);
  std::unordered_map<uint32_t, uint32_t> swapped;
  Rng rng(HashSeed({seed, kPixelSubsetStream}));
  auto at = [&](uint32_t i) {
    auto it = swapped.find(i);
    return it == swapped.end() ? i : it->second;
  };
  for (uint32_t i = 0; i < count; ++i) {
    uint32_t j = i + rng.UniformInt(n - i);
    uint32_t vi = at(i), vj = at(j);
    swapped[j] = vi;
    out.push_back(vj);
  }
  std::sort(out.begin(), out.end());
  return out;
}

ErrorMetrics CompareWithReference(const BenchReference& ref, const Image& image) {
  if (ref.pixels.empty()) return CompareImages(ref.image, image);
  if (!ref.image.SameSize(image))
    throw std::runtime_error("image and reference sizes differ");
  Image a(int(ref.pixels.size()), 1), b(int(ref.pixels.size()), 1);
  for (size_t k = 0; k < ref.pixels.size(); ++k) {
    a.pixels[k] = ref.image.pixels[ref.pixels[k]];
    b.pixels[k] = image.pixels[ref.pixels[k]];
  }
  return CompareImages(a, b);
}

}  // namespace lightfarm
