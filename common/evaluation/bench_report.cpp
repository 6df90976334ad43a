#include "common/evaluation/bench_report.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <tuple>
#include <set>
#include <sstream>
#include <thread>

#include "common/image/image_io.h"
#include "common/image/metrics.h"
#include "common/render/method_chooser.h"

namespace lightfarm {

namespace fs = std::filesystem;

namespace {

std::string Fmt(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string Seconds(double s) {
  if (s < 0) return "—";
  return s < 10 ? Fmt("%.3g s", s) : Fmt("%.1f s", s);
}

std::vector<std::string> MethodsIn(const std::vector<SettingSummary>& sums) {
  std::vector<std::string> out;
  for (const SettingSummary& s : sums)
    if (s.method != "brute" && std::find(out.begin(), out.end(), s.method) == out.end())
      out.push_back(s.method);
  return out;
}

std::vector<size_t> LightCounts(const std::vector<SettingSummary>& sums) {
  std::set<size_t> l;
  for (const SettingSummary& s : sums) l.insert(s.lights);
  return {l.begin(), l.end()};
}

const SettingSummary* Brute(const std::vector<SettingSummary>& sums, size_t lights) {
  for (const SettingSummary& s : sums)
    if (s.method == "brute" && s.lights == lights) return &s;
  return nullptr;
}

// The per-method settings closest to one common time: T is the largest of the methods' cheapest
// times (every method has a point at or below T), and each method shows its most accurate
// setting that does not exceed 1.25·T (else its cheapest).
std::vector<const SettingSummary*> EqualTimeSettings(const std::vector<SettingSummary>& sums,
                                                     size_t lights, double* t_out) {
  double T = 0;
  for (const std::string& m : MethodsIn(sums)) {
    double cheapest = -1;
    for (const SettingSummary& s : sums)
      if (s.method == m && s.lights == lights && (cheapest < 0 || s.time_s < cheapest))
        cheapest = s.time_s;
    T = std::max(T, cheapest);
  }
  std::vector<const SettingSummary*> out;
  for (const std::string& m : MethodsIn(sums)) {
    const SettingSummary* best = nullptr;
    const SettingSummary* cheapest = nullptr;
    for (const SettingSummary& s : sums) {
      if (s.method != m || s.lights != lights) continue;
      if (!cheapest || s.time_s < cheapest->time_s) cheapest = &s;
      if (s.time_s <= 1.25 * T && (!best || s.rel_l2 < best->rel_l2)) best = &s;
    }
    if (!best) best = cheapest;
    if (best) out.push_back(best);
  }
  *t_out = T;
  return out;
}

std::string PlotName(const std::string& method) {
  std::string s = method;
  for (char& c : s)
    if (c == '_') c = '-';
  return s;
}

void WritePlots(const std::vector<SettingSummary>& sums, const std::string& dir, double fixed_error,
                bool run) {
  const fs::path plots = fs::path(dir) / "plots";
  fs::create_directories(plots);
  const std::vector<size_t> counts = LightCounts(sums);
  const size_t lights = counts.back();
  const std::vector<std::string> methods = MethodsIn(sums);
  // error_vs_time.dat: one block per method (gnuplot `index`), at the largest light count.
  {
    std::ofstream f(plots / "error_vs_time.dat");
    f << "# time_s rel_l2 rel_l1 shadow_rays_per_pixel (medians), " << lights << " lights\n";
    for (const std::string& m : methods) {
      std::vector<const SettingSummary*> pts;
      for (const SettingSummary& s : sums)
        if (s.method == m && s.lights == lights && s.rel_l2 > 0) pts.push_back(&s);
      std::sort(pts.begin(), pts.end(), [](auto a, auto b) { return a->time_s < b->time_s; });
      f << "# " << m << "\n";
      for (const SettingSummary* s : pts)
        f << s->time_s << " " << s->rel_l2 << " " << s->rel_l1 << " " << s->shadow_rays_per_pixel << "\n";
      f << "\n\n";
    }
  }
  {
    std::ofstream f(plots / "error_vs_time_truth.dat");
    f << "# time_s truth_rel_l1 truth_rel_l2 fireflies (medians), " << lights << " lights; brute last\n";
    for (const std::string& m : methods) {
      std::vector<const SettingSummary*> pts;
      for (const SettingSummary& s : sums)
        if (s.method == m && s.lights == lights && std::isfinite(s.truth_rel_l1)) pts.push_back(&s);
      std::sort(pts.begin(), pts.end(), [](auto a, auto b) { return a->time_s < b->time_s; });
      f << "# " << m << "\n";
      for (const SettingSummary* s : pts) f << s->time_s << " " << s->truth_rel_l1 << " " << s->truth_rel_l2 << " " << s->fireflies << "\n";
      f << "\n\n";
    }
    f << "# brute\n";
    if (const SettingSummary* b = Brute(sums, lights))
      if (std::isfinite(b->truth_rel_l1)) f << b->time_s << " " << b->truth_rel_l1 << " " << b->truth_rel_l2 << " " << b->fireflies << "\n";
    f << "\n\n";
  }
  {
    std::ofstream f(plots / "error_vs_lights.dat");
    f << "# lights time_to_" << fixed_error << "_s (per method; brute last)\n";
    for (const std::string& m : methods) {
      f << "# " << m << "\n";
      for (size_t l : counts) {
        double t = TimeToReach(sums, m, l, fixed_error);
        if (t > 0) f << l << " " << t << "\n";
      }
      f << "\n\n";
    }
    f << "# brute\n";
    for (size_t l : counts)
      if (const SettingSummary* b = Brute(sums, l)) f << l << " " << b->time_s << "\n";
    f << "\n\n";
  }
  const SettingSummary* brute = Brute(sums, lights);
  std::ofstream gp(plots / "plots.gp");
  gp << "# Generated by lightfarm bench from results.csv (medians); run from the bench dir.\n"
        "set terminal pngcairo size 900,600 font 'DejaVu Sans,11'\n"
        "set termoption noenhanced\nset datafile separator ' '\nset logscale xy\nset grid\nset key outside right\n";
  gp << "set output 'error_vs_time.png'\nset title 'Error vs time, " << lights
     << " lights (median of repeats)'\nset xlabel 'wall time (s)'\nset ylabel 'rel_l2'\n";
  if (brute) gp << "set arrow from " << brute->time_s << ", graph 0 to " << brute->time_s
                << ", graph 1 nohead dt 2 lc rgb 'black'\n"
                << "set label 'brute " << Fmt("%.3g", brute->time_s) << " s" << (brute->estimated ? " (est.)" : "")
                << "' at " << brute->time_s << ", graph 0.95 right offset -0.5,0\n";
  gp << "plot ";
  for (size_t i = 0; i < methods.size(); ++i)
    gp << (i ? ", " : "") << "'plots/error_vs_time.dat' index " << i
       << " using 1:2 with linespoints lw 2 title '" << PlotName(methods[i]) << "'";
  if (methods.empty()) gp << "NaN notitle";
  gp << "\nunset arrow\nunset label\n";
  gp << "set output 'error_vs_time_truth.png'\nset title 'Error against the truth vs time, " << lights
     << " lights (median of repeats)'\nset xlabel 'wall time (s)'\nset ylabel 'rel_l1 against the truth'\nplot ";
  for (size_t i = 0; i < methods.size(); ++i)
    gp << "'plots/error_vs_time_truth.dat' index " << i << " using 1:2 with linespoints lw "
       << (methods[i] == "path" ? "3 dt 2" : "2") << " title '" << PlotName(methods[i]) << "', ";
  gp << "'plots/error_vs_time_truth.dat' index " << methods.size()
     << " using 1:2 with points pt 7 ps 1.5 lc rgb 'black' title 'brute (same lights)'\n";
  gp << "set output 'error_vs_lights.png'\nset title 'Time to reach rel_l2 <= "
     << Fmt("%g", 100 * fixed_error) << "% vs number of lights'\nset xlabel 'lights'\nset ylabel 'time (s)'\n";
  gp << "plot ";
  for (size_t i = 0; i < methods.size(); ++i)
    gp << "'plots/error_vs_lights.dat' index " << i << " using 1:2 with linespoints lw 2 title '"
       << PlotName(methods[i]) << "', ";
  gp << "'plots/error_vs_lights.dat' index " << methods.size()
     << " using 1:2 with linespoints lw 2 dt 2 lc rgb 'black' title 'brute'\n";
  gp.close();
  if (!run) return;
  const std::string cmd = "cd '" + dir + "' && gnuplot plots/plots.gp 2> plots/gnuplot.log";
  if (std::system(cmd.c_str()) != 0)
    spdlog::warn("bench: gnuplot failed (see {}/plots/gnuplot.log); plots not drawn", dir);
}

// Heatmap of a pixel-subset comparison: only the subset's pixels are coloured, relative to the
// subset's mean luminance (as ErrorHeatmap is to the full image's). Masked, the reference's mean
// over all pixels is coverage × the subset's mean, so the scale's top is divided by coverage.
Image SubsetHeatmap(const Image& ref, const Image& img, const std::vector<uint32_t>& pixels) {
  Image r(ref.width, ref.height), m(ref.width, ref.height);
  for (uint32_t p : pixels) {
    r.pixels[p] = ref.pixels[p];
    m.pixels[p] = img.pixels[p];
  }
  const float coverage = float(pixels.size()) / float(ref.PixelCount());
  return ErrorHeatmap(r, m, kDefaultHeatmapMaxError / coverage);
}

// A contact sheet is an illustration: failing to write one warns and leaves the report whole.
void TryWriteContactSheet(const std::vector<std::pair<std::string, std::string>>& top,
                          const std::vector<std::string>& bottom, const std::string& path) {
  try {
    WriteContactSheet(top, bottom, path);
  } catch (const std::exception& e) {
    spdlog::warn("bench: {}", e.what());
  }
}

}  // namespace

double TimeToReach(const std::vector<SettingSummary>& sums, const std::string& method,
                   size_t lights, double error) {
  const SettingPick pick = FastestWithin(sums, ErrorAgainst::kBrute, error, [&](const SettingSummary& s) {
    return s.method == method && s.lights == lights;
  });
  return pick.reached ? pick.summary->time_s : -1;
}

double TimeToReachTruth(const std::vector<SettingSummary>& sums, const std::string& method,
                        size_t lights, double error) {
  const SettingPick pick = FastestWithin(sums, ErrorAgainst::kTruth, error, [&](const SettingSummary& s) {
    return s.method == method && (lights == 0 || s.lights == lights);
  });
  return pick.reached ? pick.summary->time_s : -1;
}

const SettingSummary* BestWithin(const std::vector<SettingSummary>& sums, const std::string& method,
                                 size_t lights, double seconds) {
  const SettingSummary* best = nullptr;
  for (const SettingSummary& s : sums)
    if (s.method == method && (lights == 0 || s.lights == lights) && s.time_s <= seconds &&
        std::isfinite(s.truth_rel_l1) &&
        (!best || s.truth_rel_l1 < best->truth_rel_l1))
      best = &s;
  return best;
}

std::string MachineDescription() {
  std::string model = "unknown CPU";
  std::ifstream cpu("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpu, line))
    if (line.rfind("model name", 0) == 0) {
      model = line.substr(line.find(':') + 2);
      break;
    }
  return "nproc " + std::to_string(std::thread::hardware_concurrency()) + ", " + model;
}

void WriteBenchReport(const std::vector<BenchRow>& rows, const ReportOptions& o) {
  const std::vector<SettingSummary> sums = Summarize(rows);
  if (sums.empty()) throw std::runtime_error("bench report: no rows");
  const std::vector<size_t> counts = LightCounts(sums);
  const std::vector<std::string> methods = MethodsIn(sums);
  const size_t top_lights = counts.back();
  const BenchRow& any = rows.front();
  const std::vector<double> targets = {0.05, 0.02, 0.01};

  // The fixed error of error_vs_lights: 2%, or the smallest of 5%/10% some method reached.
  double fixed_error = 0.02;
  for (double e : {0.02, 0.05, 0.1}) {
    fixed_error = e;
    bool reached = false;
    for (const std::string& m : methods)
      for (size_t l : counts) reached = reached || TimeToReach(sums, m, l, e) > 0;
    if (reached) break;
  }
  WritePlots(sums, o.out_dir, fixed_error, o.run_gnuplot);

  std::ostringstream md;
  md << "# lightfarm bench: " << fs::path(any.scene).parent_path().filename().string() << "\n\n";
  md << "- command: `" << o.command << "`\n";
  md << "- machine: " << MachineDescription() << "; lightfarm " << LIGHTFARM_VERSION << "\n";
  md << "- scene `" << any.scene << "`, " << any.width << "x" << any.height << ", " << any.spp
     << " spp, seed " << any.seed << "\n";
  md << "- reference: brute force with the same lights, receivers and seed; ";
  if (any.reference == "full") {
    md << "full image.\n";
  } else {
    md << "exact on a seeded random subset of " << any.reference.substr(7)
       << " pixels only (`--reference-pixels`): every error below is measured on those pixels, "
          "and brute force's time and rays are extrapolated from them to the whole image "
          "(marked *est.*).\n";
  }
  md << "- every number is the median over the repeats of one setting; time is the wall time "
        "of the whole render (scene parse, receivers, lights, gather, film) in this process.\n\n";

  md << "## Time to reach an error\n\n"
     << "Fastest measured setting whose median rel_l2 is at or below the target; speedup is "
        "brute force's time over it. — : no setting of the sweep reached it.\n\n";
  md << "| lights | method |";
  for (double e : targets) md << " time to " << Fmt("%g", 100 * e) << "% | speedup |";
  md << "\n|---|---|";
  for (size_t i = 0; i < targets.size(); ++i) md << "---|---|";
  md << "\n";
  for (size_t l : counts) {
    const SettingSummary* b = Brute(sums, l);
    if (b)
      md << "| " << l << " | brute | " << Seconds(b->time_s) << (b->estimated ? " *est.*" : "")
         << " | 1 | | | | |\n";
    for (const std::string& m : methods) {
      md << "| " << l << " | " << m << " |";
      for (double e : targets) {
        double t = TimeToReach(sums, m, l, e);
        md << " " << Seconds(t) << " | "
           << (t > 0 && b ? Fmt("%.1f×", b->time_s / t) : std::string("—")) << " |";
      }
      md << "\n";
    }
  }
  md << "\n## Error versus time\n\n![error vs time](error_vs_time.png)\n\n"
     << "![time to " << Fmt("%g", 100 * fixed_error) << "% vs lights](error_vs_lights.png)\n\n";

  md << "## Every setting\n\n| lights | method | setting | runs | time | shadow rays / pixel | "
        "elements | rel_l2 | rel_l1 | peak RSS (MiB) |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const SettingSummary& s : sums)
    md << "| " << s.lights << " | " << s.method << " | `" << s.setting << "` | " << s.runs << " | "
       << Seconds(s.time_s) << (s.estimated ? " *est.*" : "") << " | "
       << Fmt("%.1f", s.shadow_rays_per_pixel) << " | " << Fmt("%.3g", s.elements) << " | "
       << Fmt("%.4f", s.rel_l2) << " | " << Fmt("%.4f", s.rel_l1) << " | "
       << (s.peak_rss_mb > 0 ? Fmt("%.0f", s.peak_rss_mb) : std::string("(cached)")) << " |\n";
  md << "\nPeak RSS is the process's high-water mark during that run (reset before each run); "
     << "per million lights and per megapixel it is the brute row's value divided by "
     << "lights/10⁶ and by pixels/10⁶.\n";

  // Against the truth: what a user sees, and how the methods compare with a path tracer.
  const BenchTruthInfo truth = ReadBenchTruthInfo(o.out_dir);
  bool any_truth = false;
  for (const SettingSummary& s : sums) any_truth = any_truth || std::isfinite(s.truth_rel_l1);
  if (truth.present && any_truth) {
    const std::vector<double> truth_targets = {0.10, 0.05, 0.02};
    md << "\n## Against the truth\n\n"
       << "- truth: " << truth.label << ".\n"
       << "- `truth rel_l1` is each run's error against it: what a user sees. Brute force's own "
          "(the first row of each light count) is the virtual lights' error (their number, the "
          "clamp, the transport they cannot carry); a method's error against brute force is its "
          "approximation of them. `fireflies`: share of pixels more than 3× above or below the "
          "truth's 3×3 local mean.\n";
    if (std::isfinite(truth.noise_rel_l1))
      md << "- the truth's own noise adds up to about " << Fmt("%.4f", truth.noise_rel_l1)
         << " to every rel_l1 below; differences smaller than that are not measured.\n";
    md << "\n### The virtual lights' own error\n\nBrute force (every virtual light, exact) against the "
          "truth, per light count: no many-light method gets closer to the truth than this with these "
          "lights.\n\n| lights | time | truth rel_l1 | truth rel_l2 | fireflies |\n|---|---|---|---|---|\n";
    for (size_t l : counts)
      if (const SettingSummary* b = Brute(sums, l); b && std::isfinite(b->truth_rel_l1))
        md << "| " << l << " | " << Seconds(b->time_s) << (b->estimated ? " *est.*" : "") << " | "
           << Fmt("%.4f", b->truth_rel_l1) << " | " << Fmt("%.4f", b->truth_rel_l2) << " | "
           << Fmt("%.2f%%", 100 * b->fireflies) << " |\n";
    // Across light counts: the cheapest way to an error may be more lights and a coarser setting.
    auto fastest = [&](const std::string& m, double e) {
      const SettingSummary* best = nullptr;
      for (const SettingSummary& s : sums)
        if (s.method == m && s.truth_rel_l1 <= e && (!best || s.time_s < best->time_s)) best = &s;
      return best;
    };
    md << "\n### Time to reach an error against the truth\n\n"
       << "Fastest measured (light count, setting) whose median truth rel_l1 is at or below the "
          "target, over every light count; `× path` is the path tracer's time over the method's "
          "(above 1: the method is faster). — : nothing measured reached it.\n\n| method |";
    for (double e : truth_targets) md << " " << Fmt("%g", 100 * e) << "% | × path |";
    md << "\n|---|";
    for (size_t i = 0; i < truth_targets.size(); ++i) md << "---|---|";
    md << "\n";
    for (const std::string& m : methods) {
      md << "| " << m << " |";
      for (double e : truth_targets) {
        const SettingSummary* s = fastest(m, e);
        const SettingSummary* p = fastest("path", e);
        md << " ";
        if (s)
          md << Seconds(s->time_s) << " (" << (m == "path" ? "" : std::to_string(s->lights) + " lights, ") << "`"
             << s->setting << "`)";
        else
          md << "—";
        md << " | " << (s && p ? Fmt("%.2f×", p->time_s / s->time_s) : std::string("—")) << " |";
      }
      md << "\n";
    }
    // Three budgets spanning the measured times (geometrically), the last one the longest run.
    double tmin = -1, tmax = 0;
    for (const SettingSummary& s : sums)
      if (s.method != "brute" && std::isfinite(s.truth_rel_l1)) {
        tmin = tmin < 0 ? s.time_s : std::min(tmin, s.time_s);
        tmax = std::max(tmax, s.time_s);
      }
    std::vector<double> budgets;
    for (int k = 1; k <= 3 && tmin > 0; ++k) budgets.push_back(tmin * std::pow(tmax / tmin, k / 3.0));
    md << "\n### Equal time\n\nEach method's most accurate (light count, setting) by median truth "
          "rel_l1 whose median time is within the budget; `× path` is the path tracer's error over "
          "the method's at that budget (above 1: the method is better, below 1: it loses).\n\n| budget | method | "
          "lights | setting | time | truth rel_l1 | × path | truth rel_l2 | fireflies |\n|---|---|---|---|---|---|---|---|---|\n";
    for (double budget : budgets) {
      const SettingSummary* path = BestWithin(sums, "path", 0, budget);
      for (const std::string& m : methods) {
        const SettingSummary* s = BestWithin(sums, m, 0, budget);
        md << "| " << Seconds(budget) << " | " << m << " | ";
        if (!s) {
          md << "— | — | | | | | |\n";
          continue;
        }
        md << (m == "path" ? std::string("—") : std::to_string(s->lights)) << " | `" << s->setting << "` | "
           << Seconds(s->time_s) << " | " << Fmt("%.4f", s->truth_rel_l1) << " | "
           << (path ? Fmt("%.2f×", path->truth_rel_l1 / s->truth_rel_l1) : std::string("—")) << " | "
           << Fmt("%.4f", s->truth_rel_l2) << " | " << Fmt("%.2f%%", 100 * s->fireflies) << " |\n";
      }
    }
    md << "\n![error against the truth vs time](error_vs_time_truth.png)\n";
    // Images and heatmaps against the truth side by side, at each budget.
    if (o.images && !truth.image.empty()) {
      const fs::path dir(o.out_dir);
      fs::create_directories(dir / "heatmaps");
      const Image timg = ReadImage((dir / truth.image).string());
      WritePNG((dir / "heatmaps/truth.png").string(), timg);
      for (size_t k = 0; k < budgets.size(); ++k) {
        std::vector<std::pair<std::string, std::string>> top = {{"truth", (dir / "heatmaps/truth.png").string()}};
        std::vector<std::string> bottom = {""};
        md << "\n#### At " << Seconds(budgets[k]) << ", against the truth\n\nHeatmap: |truth − img| luminance "
              "over the truth's mean, black = 0, pale yellow ≥ 20%.\n\n"
           << "| method | lights | setting | truth rel_l1 | image | heatmap |\n|---|---|---|---|---|---|\n";
        for (const std::string& m : methods) {
          const SettingSummary* s = BestWithin(sums, m, 0, budgets[k]);
          if (!s || s->image.empty()) continue;
          const Image img = ReadImage((dir / s->image).string());
          const std::string tag = m + "_b" + std::to_string(k + 1);
          const std::string png = "heatmaps/" + tag + "_truth.png", heat = "heatmaps/" + tag + "_truth_error.png";
          WritePNG((dir / png).string(), img);
          WritePNG((dir / heat).string(), ErrorHeatmap(timg, img));
          top.push_back({m + " " + s->setting, (dir / png).string()});
          bottom.push_back((dir / heat).string());
          md << "| " << m << " | " << (m == "path" ? std::string("—") : std::to_string(s->lights)) << " | `"
             << s->setting << "` | " << Fmt("%.4f", s->truth_rel_l1) << " | ![](" << png << ") | ![](" << heat
             << ") |\n";
        }
        const std::string sheet = "contact_sheet_truth_" + std::to_string(k + 1) + ".png";
        TryWriteContactSheet(top, bottom, (dir / sheet).string());
        md << "\n![contact sheet against the truth](" << sheet << ")\n";
      }
    }
  }

  // Heatmaps and the contact sheet at one equal-time point, for the largest light count.
  if (o.images) {
    double T = 0;
    std::vector<const SettingSummary*> eq = EqualTimeSettings(sums, top_lights, &T);
    const SettingSummary* b = Brute(sums, top_lights);
    if (b && !b->image.empty() && !eq.empty()) {
      const fs::path dir(o.out_dir);
      fs::create_directories(dir / "heatmaps");
      const Image ref = ReadImage((dir / b->image).string());
      std::vector<uint32_t> subset;
      if (any.reference != "full") {
        std::ifstream in((dir / (b->image + ".pixels")).string());
        for (uint32_t p; in >> p;) subset.push_back(p);
      }
      std::vector<std::pair<std::string, std::string>> top;
      std::vector<std::string> bottom;
      WritePNG((dir / "heatmaps/reference.png").string(), ref);
      top.push_back({"brute", (dir / "heatmaps/reference.png").string()});
      bottom.push_back("");
      md << "\n## Equal time (about " << Seconds(T) << ", " << top_lights << " lights)\n\n"
         << "Each method's most accurate setting within 1.25× of the time its slowest-starting "
            "rival needs for its cheapest setting. Heatmap: |ref − img| luminance over the "
            "reference's mean, black = 0, pale yellow ≥ 20%"
         << (subset.empty() ? "" : " (subset pixels only)") << ".\n\n| method | setting | time | rel_l2 | heatmap |\n|---|---|---|---|---|\n";
      for (const SettingSummary* s : eq) {
        if (s->image.empty()) continue;
        const Image img = ReadImage((dir / s->image).string());
        const std::string png = "heatmaps/" + s->method + ".png";
        const std::string heat = "heatmaps/" + s->method + "_error.png";
        WritePNG((dir / png).string(), img);
        WritePNG((dir / heat).string(), subset.empty() ? ErrorHeatmap(ref, img) : SubsetHeatmap(ref, img, subset));
        top.push_back({s->method + " " + s->setting, (dir / png).string()});
        bottom.push_back((dir / heat).string());
        md << "| " << s->method << " | `" << s->setting << "` | " << Seconds(s->time_s) << " | "
           << Fmt("%.4f", s->rel_l2) << " | ![](" << heat << ") |\n";
      }
      TryWriteContactSheet(top, bottom, (dir / "contact_sheet.png").string());
      md << "\n![contact sheet](contact_sheet.png)\n";
    }
  }
  std::ofstream((fs::path(o.out_dir) / "report.md").string()) << md.str();
}

}  // namespace lightfarm
