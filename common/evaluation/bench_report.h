// From a bench's rows (results.csv) to its report: medians per setting, the time each method
// needs to reach 5%, 2%, 1% rel_l2, gnuplot plots, error heatmaps at one equal-time point, a
// contact sheet and report.md. Nothing here renders; the numbers come from the CSV only.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "common/evaluation/bench_run.h"

namespace lightfarm {

// Fastest median time among a method's settings (at `lights`) whose median rel_l2 <= error;
// a negative value when no setting reached it (FastestWithin, as --target-error chooses).
double TimeToReach(const std::vector<SettingSummary>& summaries, const std::string& method,
                   size_t lights, double error);

// Same, by the median rel_l1 against the truth.
double TimeToReachTruth(const std::vector<SettingSummary>& summaries, const std::string& method,
                        size_t lights, double error);

// The most accurate setting (median truth rel_l1) of a method whose median time is within
// `seconds`; nullptr when none is.
const SettingSummary* BestWithin(const std::vector<SettingSummary>& summaries, const std::string& method,
                                 size_t lights, double seconds);

struct ReportOptions {
  std::string out_dir;
  std::string command;  // the command line that produced the rows, quoted in the report
  bool run_gnuplot = true;
  bool images = true;   // heatmaps and contact sheet (needs the rows' images)
};

// Writes report.md, plots/*.dat + plots.gp, error_vs_time.png, error_vs_lights.png,
// heatmaps/*.png and contact_sheet.png into out_dir.
void WriteBenchReport(const std::vector<BenchRow>& rows, const ReportOptions& options);

// "nproc N, CPU model" of this machine.
std::string MachineDescription();

}  // namespace lightfarm
