// `lightfarm bench`: for each light count, the brute-force reference (cached), then every
// method's sweep, each setting `repeats` times; one CSV row per run, appended and flushed as
// soon as the run ends so that an interrupted bench keeps what it measured.
#pragma once

#include <atomic>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "common/evaluation/reference.h"
#include "common/evaluation/sweeps.h"
#include "common/evaluation/truth.h"
#include "common/util/bench_table.h"
#include "common/render/render_job.h"

namespace lightfarm {

struct BenchOptions {
  std::string scene;
  std::string out_dir;
  std::vector<std::string> methods;   // empty: every registered method with a sweep
  std::string settings;               // non-empty: this sweep ("a=1;a=2") for the one method
  std::vector<size_t> lights = {kDefaultLights};
  int width = 0, height = 0;          // 0: the scene's Film
  int spp = 1;
  uint64_t seed = 0;
  std::string filter;
  std::vector<std::string> params;    // renderer --param entries shared by all runs (clamp=...)
  int repeats = 3;
  size_t reference_pixels = 0;        // 0: full-image reference
  std::string cache_dir;              // reference cache; empty: no cache
  bool keep_images = true;            // write each setting's first image (for heatmaps, contact sheet)
  // The truth every run is also measured against (truth.h): "" the scene's reference.exr or
  // else a path-traced one, "path", an image file, or "none".
  std::string truth;
  double truth_noise = 0.01;          // a path-traced truth's target rel_l1 noise
  double truth_max_seconds = 3600;    // and the time it may take
};

struct BenchProgress {
  std::function<void(const std::string& label, size_t done, size_t total)> update;
  const std::atomic<bool>* stop = nullptr;  // set (e.g. by SIGINT): finish the current run, stop
};

// What a bench measured against, for the report.
struct BenchTruthInfo {
  bool present = false;
  std::string label;  // Truth::label
  double noise_rel_l1 = NAN, noise_rel_l2 = NAN;
  std::string image;  // the truth at the bench's resolution, relative to the out dir
};

// Runs the bench, writing out_dir/results.csv (and images under out_dir/images, the truth as
// out_dir/truth.exr and truth.json). Returns the rows written. Methods that fail (a scene they
// cannot render) are logged and skipped. A sweep setting's `spp=N` sets the camera samples.
std::vector<BenchRow> RunBench(const BenchOptions& options, const BenchProgress& progress,
                               BenchTruthInfo* truth_info = nullptr);

// Reads out_dir/truth.json as RunBench wrote it (present = false when there is none).
BenchTruthInfo ReadBenchTruthInfo(const std::string& out_dir);

// Peak resident set size of this process since the last ResetPeakMemory(), in MiB.
void ResetPeakMemory();
double PeakMemoryMiB();

}  // namespace lightfarm
