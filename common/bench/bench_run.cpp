#include "common/bench/bench_run.h"

#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "common/image/image_io.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
constexpr uint64_t kRepeatSeedStream = 0xBE7C5;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

const char* kColumns[] = {"scene", "lights", "width", "height", "spp", "seed", "method",
                          "setting", "repeat", "time_total_s", "time_plan_s", "time_gather_s",
                          "shadow_rays", "shadow_rays_per_pixel", "elements",
                          "fraction_evaluated", "rel_l2", "rel_l1", "peak_rss_mb", "reference",
                          "estimated", "phases", "image"};

// Settings hold commas ("rows=50,columns=100"); the CSV keeps them space-separated so that no
// field needs quoting and plain tools (cut, gnuplot, awk) read the file.
std::string ToField(std::string s) {
  for (char& c : s)
    if (c == ',' || c == '\n') c = ' ';
  return s;
}
std::string FromField(std::string s) {
  for (char& c : s)
    if (c == ' ') c = ',';
  return s;
}

std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

struct RunResult {
  Image image;
  nlohmann::json stats;
  double plan_s = 0, gather_s = 0, total_s = 0;
};

// RenderScene, with the method's seed set apart from the job seed: repeats then differ in the
// method's random choices while the receivers and lights (and so the reference) stay the same.
RunResult RunOnce(const std::string& scene, const RenderSettings& settings, uint64_t method_seed) {
  RunResult r;
  const auto t0 = Clock::now();
  PhaseTimes times;
  Plan plan = BuildPlan(scene, settings, &times);
  for (SubMatrixTask& task : plan.tasks) task.seed = method_seed;
  r.plan_s = Since(t0);
  const auto t1 = Clock::now();
  GatherOutcome outcome = RunStagesLocally(plan, nullptr, &times);
  r.gather_s = Since(t1);
  uint64_t nan_samples = 0;
  r.image = AssembleImage(plan, outcome, &nan_samples);
  r.total_s = Since(t0);
  r.stats = MakeStats(plan, settings, outcome, nan_samples, times, r.total_s);
  return r;
}

std::string PhasesField(const nlohmann::json& phases) {
  std::string out;
  for (const auto& [name, secs] : phases.items())
    out += (out.empty() ? "" : ";") + name + "=" + Num(secs.get<double>());
  return out;
}

}  // namespace

void ResetPeakMemory() {
  // Linux >= 4.0: writing 5 resets VmHWM to the current RSS.
  std::ofstream("/proc/self/clear_refs") << "5";
}

double PeakMemoryMiB() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;  // kB
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_maxrss) / 1024.0;
}

std::string BenchCsvHeader() {
  std::string h;
  for (const char* c : kColumns) h += (h.empty() ? "" : ",") + std::string(c);
  return h;
}

std::string ToCsvLine(const BenchRow& r) {
  std::vector<std::string> f = {ToField(r.scene), std::to_string(r.lights), std::to_string(r.width),
                                std::to_string(r.height), std::to_string(r.spp),
                                std::to_string(r.seed), r.method, ToField(r.setting),
                                std::to_string(r.repeat), Num(r.time_total_s), Num(r.time_plan_s),
                                Num(r.time_gather_s), Num(r.shadow_rays),
                                Num(r.shadow_rays_per_pixel), Num(r.elements),
                                Num(r.fraction_evaluated), Num(r.rel_l2), Num(r.rel_l1),
                                Num(r.peak_rss_mb), r.reference, r.estimated ? "1" : "0",
                                ToField(r.phases), ToField(r.image)};
  std::string line;
  for (const std::string& s : f) line += (line.empty() ? "" : ",") + s;
  return line;
}

std::vector<BenchRow> ReadBenchCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::string line;
  if (!std::getline(in, line) || line != BenchCsvHeader())
    throw std::runtime_error(path + ": not a lightfarm bench results.csv (header differs)");
  std::vector<BenchRow> rows;
  const size_t ncols = std::size(kColumns);
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) f.push_back(cell);
    if (!line.empty() && line.back() == ',') f.push_back("");
    if (f.size() != ncols) throw std::runtime_error(path + ": row with " + std::to_string(f.size()) + " fields");
    BenchRow r;
    r.scene = f[0];
    r.lights = std::stoull(f[1]);
    r.width = std::stoi(f[2]);
    r.height = std::stoi(f[3]);
    r.spp = std::stoi(f[4]);
    r.seed = std::stoull(f[5]);
    r.method = f[6];
    r.setting = FromField(f[7]);
    r.repeat = std::stoi(f[8]);
    r.time_total_s = std::stod(f[9]);
    r.time_plan_s = std::stod(f[10]);
    r.time_gather_s = std::stod(f[11]);
    r.shadow_rays = std::stod(f[12]);
    r.shadow_rays_per_pixel = std::stod(f[13]);
    r.elements = std::stod(f[14]);
    r.fraction_evaluated = std::stod(f[15]);
    r.rel_l2 = std::stod(f[16]);
    r.rel_l1 = std::stod(f[17]);
    r.peak_rss_mb = std::stod(f[18]);
    r.reference = f[19];
    r.estimated = f[20] == "1";
    r.phases = f[21];
    r.image = f[22];
    rows.push_back(std::move(r));
  }
  return rows;
}

std::vector<BenchRow> RunBench(const BenchOptions& o, const BenchProgress& progress) {
  if (o.repeats < 1) throw OptionError("--repeats must be >= 1");
  if (o.lights.empty()) throw OptionError("--lights needs at least one count");
  const std::vector<MethodSweep> sweeps = SweepsFor(o.methods, o.settings);
  fs::create_directories(o.out_dir);
  const std::string csv_path = (fs::path(o.out_dir) / "results.csv").string();
  std::ofstream csv(csv_path, std::ios::trunc);
  if (!csv) throw std::runtime_error("cannot write " + csv_path);
  csv << BenchCsvHeader() << "\n" << std::flush;

  size_t total = 0, done = 0;
  for (const MethodSweep& m : sweeps) total += m.settings.size() * size_t(o.repeats);
  total = (total + 1) * o.lights.size();
  auto tick = [&](const std::string& label) {
    ++done;
    if (progress.update) progress.update(label, done, total);
  };
  auto stopped = [&] { return progress.stop && progress.stop->load(); };

  std::vector<BenchRow> rows;
  auto emit = [&](const BenchRow& row) {
    rows.push_back(row);
    csv << ToCsvLine(row) << "\n" << std::flush;  // an interrupted bench keeps finished rows
  };
  for (size_t lights : o.lights) {
    if (stopped()) break;
    RenderSettings base;
    base.width = o.width;
    base.height = o.height;
    base.spp = o.spp;
    base.seed = o.seed;
    base.filter = o.filter;
    base.lights = lights;
    base.params = o.params;
    const std::string img_dir = "images/" + std::to_string(lights);
    if (o.keep_images) fs::create_directories(fs::path(o.out_dir) / img_dir);

    // The reference (brute force with the same lights), cached.
    if (progress.update) progress.update("reference", done, total);
    ResetPeakMemory();
    ReferenceRequest req{o.scene, base, o.reference_pixels, o.cache_dir};
    BenchReference ref = GetReference(req);
    const int w = ref.image.width, h = ref.image.height;
    BenchRow brow;
    brow.scene = o.scene;
    brow.lights = ref.lights;
    brow.width = w;
    brow.height = h;
    brow.spp = o.spp;
    brow.seed = o.seed;
    brow.method = "brute";
    brow.setting = "reference";
    brow.time_total_s = ref.brute_seconds;
    brow.shadow_rays = ref.brute_shadow_rays;
    brow.shadow_rays_per_pixel = ref.brute_shadow_rays / (double(w) * h);
    brow.elements = ref.brute_elements;
    brow.fraction_evaluated = 1;
    brow.peak_rss_mb = ref.from_cache ? 0 : PeakMemoryMiB();
    brow.reference = ref.pixels.empty() ? "full" : "pixels:" + std::to_string(ref.pixels.size());
    brow.estimated = ref.extrapolated;
    if (o.keep_images) {
      brow.image = img_dir + "/reference.exr";
      WriteEXR((fs::path(o.out_dir) / brow.image).string(), ref.image);
      if (!ref.pixels.empty()) {
        std::ofstream px((fs::path(o.out_dir) / (brow.image + ".pixels")).string());
        for (uint32_t p : ref.pixels) px << p << "\n";
      }
    }
    emit(brow);
    tick("reference");

    for (const MethodSweep& m : sweeps) {
      bool failed = false;
      for (size_t si = 0; si < m.settings.size(); ++si) {
        const SweepSetting& setting = m.settings[si];
        for (int rep = 0; rep < o.repeats; ++rep) {
          if (stopped()) return rows;
          if (failed) {
            tick(m.method);
            continue;
          }
          RenderSettings s = base;
          s.method = m.method;
          s.params.insert(s.params.end(), setting.params.begin(), setting.params.end());
          const uint64_t method_seed =
              rep == 0 ? o.seed : HashSeed({o.seed, kRepeatSeedStream, uint64_t(rep)});
          RunResult run;
          ResetPeakMemory();
          try {
            run = RunOnce(o.scene, s, method_seed);
          } catch (const std::exception& e) {
            spdlog::warn("bench: {} {} failed: {} (skipping the method)", m.method, setting.label,
                         e.what());
            failed = true;
            tick(m.method);
            continue;
          }
          BenchRow row = brow;
          row.method = m.method;
          row.setting = setting.label;
          row.repeat = rep;
          row.estimated = false;
          row.time_total_s = run.total_s;
          row.time_plan_s = run.plan_s;
          row.time_gather_s = run.gather_s;
          row.phases = PhasesField(run.stats["time"]["phases"]);
          row.shadow_rays = run.stats["rays"]["shadow"].get<double>();
          row.shadow_rays_per_pixel = run.stats["rays"]["shadow_per_pixel"].get<double>();
          row.elements = run.stats["matrix"]["elements_evaluated"].get<double>();
          row.fraction_evaluated = run.stats["matrix"]["fraction_evaluated"].get<double>();
          row.peak_rss_mb = PeakMemoryMiB();
          ErrorMetrics err = CompareWithReference(ref, run.image);
          row.rel_l2 = err.rel_l2;
          row.rel_l1 = err.rel_l1;
          row.image.clear();
          if (o.keep_images && rep == 0) {
            row.image = img_dir + "/" + m.method + "_" + std::to_string(si) + ".exr";
            WriteEXR((fs::path(o.out_dir) / row.image).string(), run.image);
          }
          emit(row);
          tick(m.method);
        }
      }
    }
  }
  return rows;
}

}  // namespace lightfarm
