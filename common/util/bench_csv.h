// The bench's results table, results.csv: one row per run, written by `lightfarm bench`
// (common/evaluation/bench_run.h) and read by the cost model and the coordinator's dashboard,
// which links no evaluation code. Plain CSV: no field needs quoting, so cut, awk and gnuplot
// read it too.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
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

}  // namespace lightfarm
