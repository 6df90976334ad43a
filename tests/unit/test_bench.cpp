// lightfarm bench: the CSV and report, the reference cache, the pixel-subset reference, the
// sweeps' error ordering and --target-error's choice. Tiny renders of a copy of cornell-box.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/evaluation/bench_report.h"
#include "common/evaluation/bench_run.h"
#include "common/evaluation/cost_model.h"
#include "common/render/method_chooser.h"
#include "common/evaluation/reference.h"
#include "common/evaluation/truth.h"
#include "common/image/image_io.h"
#include "common/image/metrics.h"
#include "tests/common/test_util.h"

namespace lightfarm {
namespace test_bench {

using testing::SharedScene;
using testing::TempDir;

// A private copy of cornell-box in its own folder, so a test may edit it.
std::string CopyCornell(const TempDir& dir) {
  std::ifstream in(SharedScene("cornell-box"));
  std::stringstream text;
  text << in.rdbuf();
  return dir.Write("scene/scene.pbrt", text.str());
}

RenderSettings Tiny(size_t lights = 300) {
  RenderSettings s;
  s.width = 16;
  s.height = 16;
  s.lights = lights;
  s.seed = 7;
  return s;
}

BenchOptions TinyBench(const TempDir& dir, const std::string& scene) {
  BenchOptions o;
  o.scene = scene;
  o.out_dir = dir.Path("out");
  o.cache_dir = dir.Path("cache");
  o.lights = {300};
  o.width = o.height = 16;
  o.seed = 7;
  o.repeats = 1;
  return o;
}

TEST(Bench, CsvSchemaRoundTripAndReport) {
  TempDir dir;
  BenchOptions o = TinyBench(dir, CopyCornell(dir));
  o.methods = {"lightcuts", "sparse-completion"};
  const std::vector<BenchRow> rows = RunBench(o, {});
  const size_t settings = SweepsFor(o.methods)[0].settings.size() + SweepsFor(o.methods)[1].settings.size();
  ASSERT_EQ(rows.size(), 1 + settings);  // the brute reference, then one row per setting
  EXPECT_EQ(rows[0].method, "brute");
  EXPECT_EQ(rows[0].reference, "full");

  std::ifstream csv(dir.Path("out/results.csv"));
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header,
            "scene,lights,width,height,spp,seed,method,setting,repeat,time_total_s,time_plan_s,"
            "time_gather_s,shadow_rays,shadow_rays_per_pixel,elements,fraction_evaluated,rel_l2,"
            "rel_l1,peak_rss_mb,reference,estimated,phases,image,truth_rel_l1,truth_rel_l2,fireflies");
  const std::vector<BenchRow> back = ReadBenchCsv(dir.Path("out/results.csv"));
  ASSERT_EQ(back.size(), rows.size());
  for (size_t i = 1; i < rows.size(); ++i) {
    EXPECT_EQ(back[i].method, rows[i].method);
    EXPECT_EQ(back[i].setting, rows[i].setting);  // commas survive the CSV
    EXPECT_NEAR(back[i].rel_l2, rows[i].rel_l2, 1e-5 * rows[i].rel_l2 + 1e-12);
    EXPECT_GT(back[i].shadow_rays, 0);
    EXPECT_GT(back[i].time_total_s, 0);
    EXPECT_GT(back[i].peak_rss_mb, 0);
    EXPECT_NE(back[i].phases.find("lights="), std::string::npos);
  }

  ReportOptions ro;
  ro.out_dir = o.out_dir;
  ro.command = "test";
  WriteBenchReport(back, ro);
  std::ifstream md(dir.Path("out/report.md"));
  std::stringstream report;
  report << md.rdbuf();
  EXPECT_NE(report.str().find("| lights | method | time to 5% | speedup | time to 2% | speedup | "
                              "time to 1% | speedup |"),
            std::string::npos);
  EXPECT_NE(report.str().find("| 300 | sparse-completion |"), std::string::npos);
  for (const char* f : {"plots/plots.gp", "plots/error_vs_time.dat", "error_vs_time.png",
                        "error_vs_lights.png", "contact_sheet.png", "heatmaps/lightcuts_error.png"})
    EXPECT_TRUE(std::filesystem::exists(dir.Path(std::string("out/") + f))) << f;
}

// A bench with the path tracer and a path-traced truth: every row has its error against the
// truth, and that error is what `compare` measures between the row's image and truth.exr; the
// truth's noise is at or below the target; the report has the truth tables and plots.
TEST(Bench, EveryRowIsMeasuredAgainstThePathTracedTruth) {
  TempDir dir;
  BenchOptions o = TinyBench(dir, CopyCornell(dir));
  o.methods = {"lightcuts", "path"};
  o.truth = "path";
  o.truth_noise = 0.02;
  BenchTruthInfo info;
  const std::vector<BenchRow> rows = RunBench(o, {}, &info);
  ASSERT_TRUE(info.present);
  EXPECT_LE(info.noise_rel_l1, 0.02);
  EXPECT_GT(info.noise_rel_l1, 0.0);
  EXPECT_NE(info.label.find("path-traced"), std::string::npos);
  const Image truth = ReadImage(dir.Path("out/truth.exr"));
  ASSERT_EQ(truth.width, 16);
  bool saw_path = false;
  for (const BenchRow& r : rows) {
    ASSERT_TRUE(std::isfinite(r.truth_rel_l1)) << r.method << " " << r.setting;
    EXPECT_GE(r.fireflies, 0.0);
    if (r.image.empty()) continue;
    const ErrorMetrics e = CompareImages(truth, ReadImage(dir.Path("out/" + r.image)));
    EXPECT_NEAR(r.truth_rel_l1, e.rel_l1, 1e-5 * e.rel_l1) << r.method << " " << r.setting;
    EXPECT_NEAR(r.truth_rel_l2, e.rel_l2, 1e-5 * e.rel_l2) << r.method << " " << r.setting;
    if (r.method == "path") {
      saw_path = true;
      EXPECT_EQ(r.spp, std::stoi(r.setting.substr(4)));  // the sweep's spp=N
    }
  }
  EXPECT_TRUE(saw_path);
  // The path tracer's error against the truth falls with its samples: 1024 spp beats 4 spp.
  const std::vector<SettingSummary> sums = Summarize(rows);
  std::vector<double> path_errors;
  for (const SettingSummary& s : sums)
    if (s.method == "path") path_errors.push_back(s.truth_rel_l1);
  ASSERT_GE(path_errors.size(), 5u);
  EXPECT_LT(path_errors.back(), 0.5 * path_errors.front());

  // A second bench reuses the cached truth; the report has its sections.
  const std::vector<BenchRow> again = RunBench(o, {}, &info);
  EXPECT_NE(info.label.find("cached"), std::string::npos);
  ReportOptions ro;
  ro.out_dir = o.out_dir;
  ro.command = "test";
  WriteBenchReport(again, ro);
  std::ifstream md(dir.Path("out/report.md"));
  std::stringstream report;
  report << md.rdbuf();
  for (const char* section : {"## Against the truth", "### Time to reach an error against the truth", "### Equal time",
                              "| path |", "### The virtual lights' own error", "error_vs_time_truth.png"})
    EXPECT_NE(report.str().find(section), std::string::npos) << section;
  EXPECT_TRUE(std::filesystem::exists(dir.Path("out/error_vs_time_truth.png")));
}

// A truth from a file is area-averaged to the bench's resolution, and the runs use the box
// filter to match it.
TEST(Bench, FileTruthIsAreaAveragedAndRunsUseTheBoxFilter) {
  TempDir dir;
  BenchOptions o = TinyBench(dir, CopyCornell(dir));
  o.methods = {"lightcuts"};
  o.truth = SharedScene("cornell-box").substr(0, SharedScene("cornell-box").size() - 10) + "reference.exr";
  BenchTruthInfo info;
  const std::vector<BenchRow> rows = RunBench(o, {}, &info);
  EXPECT_NE(info.label.find("area-averaged to 16x16"), std::string::npos) << info.label;
  EXPECT_TRUE(std::isnan(info.noise_rel_l1));
  const Image truth = ReadImage(dir.Path("out/truth.exr"));
  EXPECT_NEAR(truth.MeanLuminance(), ReadImage(o.truth).MeanLuminance(), 1e-3 * truth.MeanLuminance());
  EXPECT_TRUE(testing::SameBits(truth, ResizeImage(ReadImage(o.truth), 16, 16)));
  // The brute-force reference row was rendered with the box filter.
  RenderSettings box = Tiny();
  box.method = "brute";
  box.filter = "box";
  EXPECT_TRUE(testing::SameBits(ReadImage(dir.Path("out/" + rows[0].image)), RenderScene(o.scene, box).image));
  for (const BenchRow& r : rows) EXPECT_TRUE(std::isfinite(r.truth_rel_l1)) << r.method << " " << r.setting;
}

TEST(Bench, FireflyShareCountsPixelsFarFromTheLocalMean) {
  Image truth(8, 8, RGB(1.f)), img(8, 8, RGB(1.f));
  EXPECT_EQ(FireflyShare(truth, img), 0.0);
  img.at(2, 2) = RGB(3.5f);  // more than 3× the local mean
  img.at(5, 5) = RGB(0.2f);  // less than a third of it
  img.at(6, 1) = RGB(2.5f);  // off, but within 3×
  EXPECT_DOUBLE_EQ(FireflyShare(truth, img), 2.0 / 64.0);
}

// Results written before the truth columns existed still read (the cost model cache).
TEST(Bench, CsvWithoutTruthColumnsStillReads) {
  TempDir dir;
  const std::string path = dir.Write(
      "old.csv",
      "scene,lights,width,height,spp,seed,method,setting,repeat,time_total_s,time_plan_s,time_gather_s,shadow_rays,"
      "shadow_rays_per_pixel,elements,fraction_evaluated,rel_l2,rel_l1,peak_rss_mb,reference,estimated,phases,image\n"
      "s.pbrt,300,16,16,1,7,lightcuts,error=0.1,0,1.5,0.1,1.2,100,0.4,100,0.1,0.05,0.04,20,full,0,lights=1,\n");
  const std::vector<BenchRow> rows = ReadBenchCsv(path);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].setting, "error=0.1");
  EXPECT_DOUBLE_EQ(rows[0].rel_l2, 0.05);
  EXPECT_TRUE(std::isnan(rows[0].truth_rel_l1));
}

TEST(Bench, InterruptedBenchKeepsTheRowsItFinished) {
  TempDir dir;
  BenchOptions o = TinyBench(dir, CopyCornell(dir));
  o.methods = {"lightcuts"};
  std::atomic<bool> stop{false};
  BenchProgress p;
  p.stop = &stop;
  p.update = [&](const std::string&, size_t done, size_t) { stop.store(done >= 3); };
  const std::vector<BenchRow> rows = RunBench(o, p);
  EXPECT_EQ(rows.size(), 3u);
  EXPECT_EQ(ReadBenchCsv(dir.Path("out/results.csv")).size(), 3u);
}

TEST(Bench, ErrorDecreasesAsTheBudgetGrows) {
  TempDir dir;
  BenchOptions o = TinyBench(dir, CopyCornell(dir));
  o.lights = {3000};
  o.width = o.height = 20;
  o.repeats = 3;
  o.keep_images = false;
  const std::vector<SettingSummary> sums = Summarize(RunBench(o, {}));
  for (const std::string& method : SweptMethodNames()) {
    std::vector<const SettingSummary*> mine;
    for (const SettingSummary& s : sums)
      if (s.method == method) mine.push_back(&s);
    ASSERT_GE(mine.size(), 5u) << method;
    EXPECT_EQ(mine.front()->runs, 3);
    // Median over repeats: the largest budget beats the smallest, and no setting of the upper
    // half of the sweep is worse than its cheapest (sparse-completion's error moves in steps at
    // this size: neighbouring rates may give the same image).
    EXPECT_LT(mine.back()->rel_l2, mine.front()->rel_l2) << method;
    for (size_t i = mine.size() / 2; i < mine.size(); ++i)
      EXPECT_LE(mine[i]->rel_l2, mine.front()->rel_l2) << method << " " << mine[i]->setting;
    EXPECT_LT(mine.front()->shadow_rays, sums.front().shadow_rays) << method;  // brute's
  }
}

TEST(BenchReference, CachedReferenceIsReusedAndInvalidated) {
  TempDir dir;
  const std::string scene = CopyCornell(dir);
  ReferenceRequest req{scene, Tiny(), 0, dir.Path("cache")};
  const uint64_t before = ReferenceComputations();
  BenchReference first = GetReference(req);
  EXPECT_FALSE(first.from_cache);
  EXPECT_EQ(ReferenceComputations(), before + 1);
  BenchReference second = GetReference(req);
  EXPECT_TRUE(second.from_cache);
  EXPECT_EQ(ReferenceComputations(), before + 1);  // loaded, not recomputed
  EXPECT_EQ(second.key, first.key);
  ASSERT_TRUE(second.image.SameSize(first.image));
  for (size_t i = 0; i < first.image.PixelCount(); ++i)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(second.image.pixels[i][c], first.image.pixels[i][c]);

  // Another light set: a new reference.
  ReferenceRequest more = req;
  more.settings.lights = 400;
  EXPECT_FALSE(GetReference(more).from_cache);
  EXPECT_EQ(ReferenceComputations(), before + 2);
  // A renderer parameter that changes the matrix: a new reference.
  ReferenceRequest clamp = req;
  clamp.settings.params = {"clamp=0.02"};
  EXPECT_FALSE(GetReference(clamp).from_cache);
  EXPECT_EQ(ReferenceComputations(), before + 3);
  // Files written beside the scene that it does not name do not matter...
  dir.Write("scene/notes.txt", "unrelated");
  EXPECT_TRUE(GetReference(req).from_cache);
  // ...an edit of the scene does.
  std::ofstream(scene, std::ios::app) << "\n# edited\n";
  BenchReference edited = GetReference(req);
  EXPECT_FALSE(edited.from_cache);
  EXPECT_NE(edited.key, first.key);
  EXPECT_EQ(ReferenceComputations(), before + 4);
}

TEST(BenchReference, PixelSubsetEqualsTheFullReferenceOnItsPixels) {
  TempDir dir;
  const std::string scene = CopyCornell(dir);
  RenderSettings s = Tiny();
  s.spp = 2;
  s.filter = "gaussian";  // several samples per pixel with unequal weights
  const BenchReference full = GetReference({scene, s, 0, ""});
  const BenchReference subset = GetReference({scene, s, 37, ""});
  ASSERT_EQ(subset.pixels.size(), 37u);
  EXPECT_TRUE(subset.extrapolated);
  std::vector<uint8_t> in(full.image.PixelCount(), 0);
  size_t nonzero = 0;
  for (uint32_t p : subset.pixels) {
    in[p] = 1;
    for (int c = 0; c < 3; ++c) EXPECT_EQ(subset.image.pixels[p][c], full.image.pixels[p][c]) << p;
    nonzero += full.image.pixels[p].Luminance() > 0;
  }
  EXPECT_GT(nonzero, 20u);
  for (size_t p = 0; p < in.size(); ++p) {
    if (!in[p]) {
      EXPECT_EQ(subset.image.pixels[p].Luminance(), 0.f);
    }
  }
  // Measured on the subset, the full reference has no error; a perturbed pixel outside the
  // subset is not seen, one inside is.
  Image img = full.image;
  EXPECT_EQ(CompareWithReference(subset, img).rel_l2, 0.0);
  size_t outside = 0;
  while (in[outside]) ++outside;
  img.pixels[outside] = img.pixels[outside] * 2.f + RGB(1.f);
  EXPECT_EQ(CompareWithReference(subset, img).rel_l2, 0.0);
  img.pixels[subset.pixels[0]] = img.pixels[subset.pixels[0]] * 2.f + RGB(1.f);
  EXPECT_GT(CompareWithReference(subset, img).rel_l2, 0.0);
  // Brute force's extrapolated cost is the full one within the subset's sampling noise.
  EXPECT_NEAR(subset.brute_shadow_rays / full.brute_shadow_rays, 1.0, 0.35);
}

// Media rows (eye segments) belong to a pixel's reference too: the subset brute force of a media
// scene must sum them exactly as the full render does (it once summed the shading points only).
TEST(BenchReference, PixelSubsetOfAMediaSceneIncludesInScatteredLight) {
  RenderSettings s = Tiny(200);
  s.width = s.height = 12;
  const std::string scene = SharedScene("volumetric-caustic");
  const BenchReference full = GetReference({scene, s, 0, ""});
  const BenchReference subset = GetReference({scene, s, 29, ""});
  ASSERT_EQ(subset.pixels.size(), 29u);
  size_t nonzero = 0;
  for (uint32_t p : subset.pixels) {
    for (int c = 0; c < 3; ++c) EXPECT_EQ(subset.image.pixels[p][c], full.image.pixels[p][c]) << p;
    nonzero += full.image.pixels[p].Luminance() > 0;
  }
  EXPECT_GT(nonzero, 20u);
  EXPECT_EQ(CompareWithReference(subset, full.image).rel_l2, 0.0);
}

TEST(BenchReference, PixelSubsetIsSeededAndDistinct) {
  const std::vector<uint32_t> a = ReferencePixelSubset(64, 32, 500, 3);
  EXPECT_EQ(a, ReferencePixelSubset(64, 32, 500, 3));
  EXPECT_NE(a, ReferencePixelSubset(64, 32, 500, 4));
  ASSERT_EQ(a.size(), 500u);
  for (size_t i = 1; i < a.size(); ++i) EXPECT_LT(a[i - 1], a[i]);
  EXPECT_LT(a.back(), 64u * 32u);
  EXPECT_EQ(ReferencePixelSubset(4, 4, 100, 1).size(), 16u);
}

BenchRow Row(const std::string& setting, double time, double err, int rep) {
  BenchRow r;
  r.method = "lightcuts";
  r.setting = setting;
  r.lights = 1000;
  r.width = r.height = 10;
  r.spp = 1;
  r.time_total_s = time;
  r.rel_l2 = err;
  r.repeat = rep;
  return r;
}

TEST(BenchCostModel, TargetErrorPicksTheCheapestSettingThatReachesItByMedian) {
  std::vector<BenchRow> rows = {
      Row("error=0.1", 1.0, 0.06, 0),  Row("error=0.1", 1.2, 0.04, 1),  Row("error=0.1", 0.9, 0.05, 2),
      Row("error=0.05", 2.0, 0.03, 0), Row("error=0.05", 2.2, 0.01, 1), Row("error=0.05", 2.1, 0.019, 2),
      Row("error=0.02", 4.0, 0.008, 0), Row("error=0.02", 4.1, 0.009, 1), Row("error=0.02", 3.9, 0.007, 2)};
  RenderSettings s;
  s.method = "lightcuts";
  s.lights = 1000;
  s.width = s.height = 20;  // 4x the bench's pixels
  const MethodChooser& chooser = MethodChooser::BuiltIn();
  MethodChoice c = chooser.ForTarget("lightcuts", 0.02, rows, s);
  EXPECT_EQ(c.basis, ChoiceBasis::kBenchAgainstBrute);
  EXPECT_TRUE(c.reached);
  EXPECT_EQ(c.setting, "error=0.05");  // median 0.019
  EXPECT_EQ(c.params, std::vector<std::string>{"error=0.05"});
  EXPECT_DOUBLE_EQ(c.estimated_error, 0.019);
  EXPECT_DOUBLE_EQ(c.predicted_s, 4 * 2.1);
  EXPECT_EQ(chooser.ForTarget("lightcuts", 0.05, rows, s).setting, "error=0.1");
  // Unreachable: the most accurate, said so.
  MethodChoice hard = chooser.ForTarget("lightcuts", 0.001, rows, s);
  EXPECT_EQ(hard.setting, "error=0.02");
  EXPECT_FALSE(hard.reached);
  EXPECT_NE(hard.source.find("no setting reached"), std::string::npos);
  // No bench rows for the method: the documented default, no prediction.
  MethodChoice d = chooser.ForTarget("sparse-completion", 0.02, rows, s);
  EXPECT_EQ(d.basis, ChoiceBasis::kDocumentedDefault);
  EXPECT_EQ(d.setting, "rate=0.1");
  EXPECT_LT(d.predicted_s, 0);
  EXPECT_THROW(chooser.ForTarget("brute", 0.02, {}, s), OptionError);
  EXPECT_THROW(chooser.ForTarget("auto", 0.02, rows, s), OptionError);  // auto needs a truth
  EXPECT_THROW(chooser.ForTarget("lightcuts", 0, rows, s), OptionError);
}

TEST(BenchSweeps, EveryRegisteredMethodWithASweepLineIsSwept) {
  const std::vector<std::string> names = SweptMethodNames();
  for (const char* m : {"mrcs", "lightcuts", "sparse-completion"})
    EXPECT_NE(std::find(names.begin(), names.end(), m), names.end()) << m;
  for (const MethodSweep& sweep : SweepsFor({})) EXPECT_GE(sweep.settings.size(), 5u) << sweep.method;
  EXPECT_THROW(SweepsFor({"no-such-method"}), OptionError);
  const MethodSweep mrcs = SweepsFor({"mrcs"})[0];
  EXPECT_EQ(mrcs.settings[1].params, (std::vector<std::string>{"rows=50", "columns=100"}));
}

TEST(BenchSweeps, SettingsReplaceTheTablesLineForOneMethod) {
  const std::vector<MethodSweep> custom =
      SweepsFor({"adaptive-completion"}, "rho=0.1,sigma=0.01;rho=0.2,sigma=0.002");
  ASSERT_EQ(custom.size(), 1u);
  EXPECT_EQ(custom[0].method, "adaptive-completion");
  ASSERT_EQ(custom[0].settings.size(), 2u);
  EXPECT_EQ(custom[0].settings[0].label, "rho=0.1,sigma=0.01");
  EXPECT_EQ(custom[0].settings[1].params, (std::vector<std::string>{"rho=0.2", "sigma=0.002"}));
  // Empty settings: the table's sweep
  EXPECT_EQ(SweepsFor({"mrcs"}, "")[0].settings.size(), SweepsFor({"mrcs"})[0].settings.size());
  EXPECT_THROW(SweepsFor({}, "rho=0.1"), OptionError);                       // every method
  EXPECT_THROW(SweepsFor({"mrcs", "lightcuts"}, "rows=10"), OptionError);    // two methods
  EXPECT_THROW(SweepsFor({"mrcs"}, ";;"), OptionError);                      // no setting
  EXPECT_THROW(SweepsFor({"mrcs"}, "rows=10,columns"), OptionError);         // not KEY=VALUE
  EXPECT_THROW(SweepsFor({"mrcs"}, "=10"), OptionError);
}

}  // namespace test_bench
}  // namespace lightfarm
