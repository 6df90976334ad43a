// `lightfarm bench SCENE --out-dir DIR ...`: what accuracy costs in time. Sweeps every method's
// quality knob (the path tracer's samples among them) against a cached brute-force reference
// with the same lights and against the truth (a converged image: truth.h), and writes
// results.csv (a row per run, flushed as it ends), plots, heatmaps, a contact sheet and
// report.md (common/evaluation/). Ctrl-C stops after the current run and still writes the report.
#include <tbb/global_control.h>

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <iostream>
#include <sstream>

#include "cli/commands.h"
#include "cli/progress.h"
#include "cli/render_options.h"
#include "cli/target_error.h"
#include "common/evaluation/cost_model.h"
#include "common/evaluation/bench_report.h"
#include "common/evaluation/bench_run.h"
#include "common/util/error.h"

namespace lightfarm::cli {

namespace {

std::atomic<bool> g_stop{false};

extern "C" void OnInterrupt(int) {
  g_stop.store(true);
  std::signal(SIGINT, SIG_DFL);  // a second Ctrl-C ends the process at once
}

struct BenchArgs {
  std::string scene, out_dir, methods, settings, lights = std::to_string(kDefaultLights), resolution, filter, cache_dir, truth;
  double truth_noise = 0.01, truth_max_seconds = 3600;
  std::vector<std::string> params;
  int spp = 1, repeats = 3, threads = 0;
  unsigned long long seed = 0;
  size_t reference_pixels = 0;
  bool no_plots = false;
};

std::vector<std::string> SplitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}


// This process's command line, for the report (quoted as run).
std::string CommandLine() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string out;
  for (char c : all) out += c == '\0' ? ' ' : c;
  while (!out.empty() && out.back() == ' ') out.pop_back();
  return out;
}

void RunBenchCommand(const BenchArgs& a) {
  BenchOptions o;
  o.scene = a.scene;
  o.out_dir = a.out_dir;
  o.methods = SplitList(a.methods);
  o.settings = a.settings;
  o.lights.clear();
  for (const std::string& n : SplitList(a.lights)) {
    try {
      o.lights.push_back(size_t(std::stoull(n)));
    } catch (const std::exception&) {
      throw OptionError("--lights expects N[,N2,...], got \"" + a.lights + "\"");
    }
    if (o.lights.back() < 1) throw OptionError("--lights must be >= 1");
  }
  if (!a.resolution.empty()) {
    RenderOptionArgs r;
    r.resolution = a.resolution;
    RenderSettings s = ToRenderSettings(r);
    o.width = s.width;
    o.height = s.height;
  }
  o.spp = a.spp;
  o.seed = a.seed;
  o.filter = a.filter;
  o.params = a.params;
  o.repeats = a.repeats;
  o.reference_pixels = a.reference_pixels;
  o.cache_dir = a.cache_dir.empty() ? DefaultBenchCacheDir() : a.cache_dir;
  o.truth = a.truth;
  o.truth_noise = a.truth_noise;
  o.truth_max_seconds = a.truth_max_seconds;

  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0)
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  size_t(a.threads));
  std::signal(SIGINT, OnInterrupt);
  ProgressBar bar;
  BenchProgress progress;
  progress.stop = &g_stop;
  progress.update = [&](const std::string& label, size_t done, size_t total) {
    bar.Update(label, done, total);
  };
  std::vector<BenchRow> rows = RunBench(o, progress);
  bar.Finish();
  std::signal(SIGINT, SIG_DFL);
  if (g_stop.load()) std::cerr << "bench: interrupted; " << rows.size() << " rows kept in results.csv\n";
  if (rows.empty()) return;
  ReportOptions ro;
  ro.out_dir = o.out_dir;
  ro.command = CommandLine();
  ro.run_gnuplot = !a.no_plots;
  WriteBenchReport(rows, ro);
  // A copy where `render --target-error` looks for this scene's cost model.
  const std::filesystem::path model = CostModelPath(o.cache_dir, o.scene);
  std::filesystem::create_directories(model.parent_path());
  std::filesystem::copy_file(std::filesystem::path(o.out_dir) / "results.csv", model,
                             std::filesystem::copy_options::overwrite_existing);
  const std::filesystem::path truth = std::filesystem::path(o.out_dir) / "truth.exr";
  std::error_code ec;
  std::filesystem::remove(TruthModelPath(o.cache_dir, o.scene), ec);
  if (std::filesystem::exists(truth))
    std::filesystem::copy_file(truth, TruthModelPath(o.cache_dir, o.scene),
                               std::filesystem::copy_options::overwrite_existing);
  std::cerr << "bench: " << rows.size() << " runs -> " << o.out_dir << "/report.md\n";
  if (g_stop.load()) std::exit(130);
}

}  // namespace

void AddBenchCommand(CLI::App& app) {
  auto a = std::make_shared<BenchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "bench", "Error versus time of every method's quality knob against brute force and the truth");
  cmd->add_option("scene", a->scene, "pbrt-v4 scene file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out-dir", a->out_dir, "Where results.csv, plots and report.md go")->required();
  cmd->add_option("--methods", a->methods, "Comma-separated methods (default: all with a sweep)");
  cmd->add_option("--settings", a->settings,
                  "With one method in --methods: its settings instead of the built-in sweep, "
                  "';'-separated, each a ','-separated KEY=VALUE list (cheapest first)");
  cmd->add_option("--lights", a->lights, "Virtual light counts, N[,N2,...]")->capture_default_str();
  cmd->add_option("--resolution", a->resolution, "WxH (default: the scene's Film)");
  cmd->add_option("--spp", a->spp, "Camera samples per pixel")->check(CLI::Range(1, 4096));
  cmd->add_option("--seed", a->seed, "Job seed (lights, receivers; repeats vary the method's seed)");
  cmd->add_option("--filter", a->filter, "Override the scene's pixel filter")
      ->check(CLI::IsMember({"box", "triangle", "gaussian", "mitchell", "sinc"}));
  cmd->add_option("--param", a->params, "Renderer parameter KEY=VALUE for every run (clamp=...)");
  cmd->add_option("--repeats", a->repeats, "Runs per setting (median reported)")
      ->check(CLI::Range(1, 1000))->capture_default_str();
  cmd->add_option("--reference-pixels", a->reference_pixels,
                  "Exact brute force on this many seeded random pixels only; errors are measured "
                  "there (0: the full image)");
  cmd->add_option("--cache-dir", a->cache_dir,
                  "Reference cache (default: $LIGHTFARM_CACHE/bench or ~/.cache/lightfarm/bench)");
  cmd->add_option("--truth", a->truth,
                  "What every run is also measured against: an image FILE (area-averaged to the bench's "
                  "resolution), `path` (rendered here until --truth-noise, cached), or `none`. Default: the "
                  "scene's reference.exr when one sits beside it, else `path`");
  cmd->add_option("--truth-noise", a->truth_noise,
                  "A path-traced truth's target noise: the rel_l1 its own noise adds")
      ->check(CLI::Range(1e-5, 0.5))->capture_default_str();
  cmd->add_option("--truth-max-seconds", a->truth_max_seconds, "Longest a path-traced truth may render")
      ->check(CLI::Range(1.0, 1e7))->capture_default_str();
  cmd->add_option("--threads", a->threads, "Threads (0 = all cores)")->check(CLI::Range(0, 4096));
  cmd->add_flag("--no-plots", a->no_plots, "Write the gnuplot script and data but do not run gnuplot");
  cmd->callback([a] { RunBenchCommand(*a); });
}

}  // namespace lightfarm::cli
