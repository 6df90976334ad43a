#include "common/evaluation/bench_run.h"

#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>

#include "common/image/image_io.h"
#include "common/util/rng.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
constexpr uint64_t kRepeatSeedStream = 0xBE7C5;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

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

BenchTruthInfo ReadBenchTruthInfo(const std::string& out_dir) {
  BenchTruthInfo info;
  std::ifstream in(fs::path(out_dir) / "truth.json");
  if (!in) return info;
  const nlohmann::json j = nlohmann::json::parse(in);
  info.present = true;
  info.label = j.value("label", "");
  info.image = j.value("image", "");
  info.noise_rel_l1 = j["noise_rel_l1"].is_number() ? j["noise_rel_l1"].get<double>() : std::nan("");
  info.noise_rel_l2 = j["noise_rel_l2"].is_number() ? j["noise_rel_l2"].get<double>() : std::nan("");
  return info;
}

std::vector<BenchRow> RunBench(const BenchOptions& options, const BenchProgress& progress,
                               BenchTruthInfo* truth_info) {
  BenchOptions o = options;
  if (o.repeats < 1) throw OptionError("--repeats must be >= 1");
  const std::string truth_source = o.truth.empty() ? DefaultTruthSource(o.scene) : o.truth;
  const bool use_truth = truth_source != "none";
  // A truth image at another resolution is area-averaged to the bench's, which is a box filter
  // over the bench's pixels: render with that filter too, or the filters' difference is measured.
  if (use_truth && truth_source != "path" && o.filter.empty() && o.width > 0) {
    const ImageSize file = ReadImageSize(truth_source);  // the header only: GetTruth reads the pixels
    if (file.width != o.width || file.height != o.height) {
      o.filter = "box";
      spdlog::info("bench: the truth {} ({}x{}) is area-averaged to {}x{}, so every run uses the box filter "
                   "(--filter overrides)", truth_source, file.width, file.height, o.width, o.height);
    }
  }
  std::optional<Truth> truth;
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
    if (use_truth && !truth) {
      if (progress.update) progress.update("truth", done, total);
      TruthRequest tr;
      tr.scene = o.scene;
      tr.source = truth_source;
      tr.width = w;
      tr.height = h;
      tr.filter = o.filter;
      tr.seed = o.seed;
      tr.noise = o.truth_noise;
      tr.max_seconds = o.truth_max_seconds;
      tr.cache_dir = o.cache_dir;
      truth = GetTruth(tr);
      WriteEXR((fs::path(o.out_dir) / "truth.exr").string(), truth->image);
      nlohmann::json j = {{"label", truth->label}, {"source", truth->source}, {"image", "truth.exr"},
                          {"passes", truth->passes}, {"spp", truth->spp}, {"seconds", truth->seconds}};
      j["noise_rel_l1"] = std::isfinite(truth->noise_rel_l1) ? nlohmann::json(truth->noise_rel_l1) : nlohmann::json();
      j["noise_rel_l2"] = std::isfinite(truth->noise_rel_l2) ? nlohmann::json(truth->noise_rel_l2) : nlohmann::json();
      std::ofstream(fs::path(o.out_dir) / "truth.json") << j.dump(2) << "\n";
      if (truth_info) *truth_info = ReadBenchTruthInfo(o.out_dir);
    }
    auto measure_truth = [&](const Image& image, BenchRow* row) {
      if (!truth) return;
      const TruthMetrics m = CompareWithTruth(*truth, image);
      row->truth_rel_l1 = m.rel_l1;
      row->truth_rel_l2 = m.rel_l2;
      row->fireflies = m.fireflies;
    };
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
    // Brute force against the truth: the virtual lights' own error (count, clamp, what they
    // cannot carry). Only a full-image reference has an image to compare.
    if (ref.pixels.empty()) measure_truth(ref.image, &brow);
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
          for (const std::string& p : setting.params) {
            // `spp=N` in a sweep is the camera samples (the path method's knob), not a parameter.
            if (p.rfind("spp=", 0) == 0) {
              s.spp = int(std::stol(p.substr(4)));
              if (s.spp < 1) throw OptionError("sweep setting " + p + ": spp must be >= 1");
            } else {
              s.params.push_back(p);
            }
          }
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
          row.spp = run.stats["spp"].get<int>();
          measure_truth(run.image, &row);
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
