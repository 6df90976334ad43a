// The bench's results table, results.csv: one row per run, written by `lightfarm bench`
// (common/evaluation/bench_run.h), summarised per setting, and read by the method chooser
// (common/render/method_chooser.h), the bench's reports and the coordinator's dashboard, which
// links no evaluation code. Plain CSV: no field needs quoting, so cut, awk and gnuplot read it.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <istream>
#include <string>
#include <vector>

namespace lightfarm {

// One row of results.csv.
struct BenchRow {
  std::string scene, method, setting;
  size_t lights = 0;
  int width = 0, height = 0, spp = 0;
  uint64_t seed = 0;
  int repeat = 0;
  double time_total_s = 0, time_plan_s = 0, time_gather_s = 0;
  std::string phases;  // name=seconds;...
  double shadow_rays = 0, shadow_rays_per_pixel = 0, elements = 0, fraction_evaluated = 0;
  double rel_l2 = 0, rel_l1 = 0;  // against same-lights brute force
  // Against the truth (NaN without one, or for a pixel-subset brute-force reference row).
  double truth_rel_l1 = NAN, truth_rel_l2 = NAN, fireflies = NAN;
  double peak_rss_mb = 0;
  std::string reference;  // "full" or "pixels:N"
  bool estimated = false;  // brute rows of a pixel-subset reference: time and rays extrapolated
  std::string image;      // PNG/EXR of this run (first repeat), relative to the out dir
};

std::string BenchCsvHeader();
std::string ToCsvLine(const BenchRow& row);
// Parses results.csv by its header's column names (files written before the truth columns
// existed read with NaN there); throws std::runtime_error on a malformed file.
std::vector<BenchRow> ReadBenchCsv(const std::string& path);
// The same from a stream; `name` names it in errors.
std::vector<BenchRow> ParseBenchCsv(std::istream& in, const std::string& name);

// The median over repeats of one (light count, method, setting).
struct SettingSummary {
  size_t lights = 0;
  std::string method, setting;
  int runs = 0;
  double time_s = 0, rel_l2 = 0, rel_l1 = 0, shadow_rays_per_pixel = 0, shadow_rays = 0;
  double elements = 0, peak_rss_mb = 0;
  double truth_rel_l1 = NAN, truth_rel_l2 = NAN, fireflies = NAN;  // NaN: no truth
  bool estimated = false;
  std::string image;  // first repeat's image
};

// One summary per (lights, method, setting) in the order the rows first appear.
std::vector<SettingSummary> Summarize(const std::vector<BenchRow>& rows);

// A setting's label is its --param entries, comma-joined: splits "a=1,b=2" into {"a=1", "b=2"}.
std::vector<std::string> SplitParams(const std::string& label);

}  // namespace lightfarm
