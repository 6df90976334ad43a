// Progressive references on the farm: passes run by worker processes or the embedded farm give
// the direct average of independent renders bit for bit; --until-noise stops at the first pass
// below its target; a killed coordinator keeps every finished pass; a running job's result is
// the mean of its passes so far, and a cancelled one keeps them.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

#include "cli/embedded_farm.h"
#include "common/render/progressive.h"
#include "common/render/render_job.h"
#include "common/scene/scene_cache.h"
#include "coordinator/job_progress.h"
#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_progressive_farm {

using namespace lightfarm::testing;

RenderSettings PassSettings(uint64_t seed, size_t lights, int side) {
  RenderSettings s;
  s.width = s.height = side;
  s.lights = lights;
  s.seed = seed;
  s.params = {"rows_per_slice=64"};
  return s;
}

// The mean of passes 0..n-1 of a job seeded `seed`, rendered one by one in this process and
// averaged directly (Σ / n per channel in double).
Image DirectAverage(uint64_t seed, uint32_t n, size_t lights, int side) {
  std::vector<Image> passes;
  for (uint32_t k = 0; k < n; ++k)
    passes.push_back(RenderScene(ExampleCornellBox(), PassSettings(PassSeed(seed, k), lights, side)).image);
  Image out(side, side);
  for (size_t i = 0; i < out.PixelCount(); ++i)
    for (int c = 0; c < 3; ++c) {
      double sum = 0;
      for (const Image& p : passes) sum += double(p.pixels[i][c]);
      out.pixels[i][c] = float(sum / double(n));
    }
  return out;
}

Image ExrImage(const TempDir& dir, const std::string& name, const std::string& bytes) {
  std::ofstream(dir.Path(name), std::ios::binary) << bytes;
  return ReadImage(dir.Path(name));
}

// The estimates a status call reports, from plain numbers.
TEST(JobProgress, StageAndPassEstimates) {
  // The final stage's pace so far times the tasks left; unknown before it or before a task.
  EXPECT_DOUBLE_EQ(StageEtaSeconds(10, 40, 0, true, 5.0), 15.0);
  EXPECT_DOUBLE_EQ(StageEtaSeconds(20, 40, 10, true, 5.0), 10.0);  // 10 done in this stage
  EXPECT_LT(StageEtaSeconds(10, 40, 10, true, 5.0), 0.0);
  EXPECT_LT(StageEtaSeconds(10, 40, 0, false, 5.0), 0.0);
  // Passes: 8 left at 1 s each, 0.5 s of the running one spent...
  PassAccumulator acc;
  acc.Add(Image(2, 2), 1.0);
  acc.Add(Image(2, 2), 1.0);
  PassPlan plan;
  plan.passes = 10;
  EXPECT_DOUBLE_EQ(PassesEtaSeconds(plan, acc, acc.Noise(), 0.5), 7.5);
  // ...capped by the time limit (2 s spent of 4, plus the running pass)...
  plan.time_limit_s = 4;
  EXPECT_DOUBLE_EQ(PassesEtaSeconds(plan, acc, acc.Noise(), 0.5), 2.5);
  // ...and never negative.
  EXPECT_DOUBLE_EQ(PassesEtaSeconds(plan, acc, acc.Noise(), 60.0), 0.0);
}

TEST(Progressive, PassesOnWorkersAndEmbeddedEqualTheDirectAverageBitForBit) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  auto w1 = StartWorker(dir, coordinator.address());
  auto w2 = StartWorker(dir, coordinator.address());
  const std::vector<std::string> args = {"--method", "brute", "--resolution", "24x24", "--lights", "2000",
                                         "--seed", "11", "--param", "rows_per_slice=64", "--quiet"};
  auto with = [&](std::vector<std::string> a) {
    a.insert(a.end(), args.begin(), args.end());
    return a;
  };
  CliResult farm = RunCli(dir, with({"submit", ExampleCornellBox(), "--server", coordinator.address(), "--wait",
                                     "--passes", "3", "--out", dir.Path("farm.exr"), "--stats", dir.Path("farm.json")}));
  ASSERT_EQ(farm.exit_code, 0) << farm.err;
  CliResult embedded = RunCli(dir, with({"render", ExampleCornellBox(), "--passes", "3", "--workers", "1", "--out",
                                         dir.Path("embedded.exr"), "--stats", dir.Path("embedded.json")}));
  ASSERT_EQ(embedded.exit_code, 0) << embedded.err;
  const Image direct = DirectAverage(11, 3, 2000, 24);
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("farm.exr")), direct));
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("embedded.exr")), direct));
  const nlohmann::json stats = nlohmann::json::parse(Slurp(dir.Path("farm.json")));
  EXPECT_EQ(stats["passes"], 3);
  EXPECT_EQ(stats["pass_times_s"].size(), 3u);
  EXPECT_GT(stats["noise"]["rel_stderr"].get<double>(), 0.0);
  EXPECT_GT(stats["noise"]["p90_rel_stderr"].get<double>(), 0.0);
  EXPECT_EQ(stats["seed"], 11);
  // One pass is the ordinary job, bit for bit.
  CliResult one = RunCli(dir, with({"render", ExampleCornellBox(), "--passes", "1", "--out", dir.Path("one.exr")}));
  ASSERT_EQ(one.exit_code, 0) << one.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("one.exr")),
                       RenderScene(ExampleCornellBox(), PassSettings(11, 2000, 24)).image));
}

TEST(Progressive, UntilNoiseStopsAtTheFirstPassBelowTheTarget) {
  RenderSettings s = PassSettings(21, 300, 16);
  s.progressive.passes = 200;
  s.progressive.until_noise = 0.2;
  const EmbeddedRender out = RenderOnEmbeddedFarm(ExampleCornellBox(), s, 2);
  // The same passes accumulated here: the first count at which the estimate is below the target.
  PassAccumulator acc;
  uint32_t expected = 0;
  for (uint32_t k = 0; k < s.progressive.passes && !expected; ++k) {
    acc.Add(RenderScene(ExampleCornellBox(), PassSettings(PassSeed(21, k), 300, 16)).image, 0);
    if (acc.passes() >= PassPlan::kMinNoisePasses && acc.Noise().worst() < s.progressive.until_noise)
      expected = acc.passes();
  }
  ASSERT_GT(expected, PassPlan::kMinNoisePasses);
  EXPECT_EQ(out.stats["passes"], expected);
  EXPECT_LT(std::max(out.stats["noise"]["rel_stderr"].get<double>(), out.stats["noise"]["p90_rel_stderr"].get<double>()),
            0.2);
  EXPECT_TRUE(SameBits(out.image, acc.Mean()));
}

TEST(Progressive, KilledCoordinatorKeepsEveryFinishedPass) {
  TempDir dir;
  const std::string state = dir.Path("state");
  auto coordinator = std::make_unique<CoordinatorProcess>(dir, state, std::vector<std::string>{"--lease-timeout", "2"});
  const int port = coordinator->port();
  auto worker = StartWorker(dir, coordinator->address());
  RenderSettings s = PassSettings(31, 6000, 32);
  s.progressive.passes = 4;
  std::string job;
  uint32_t done_before = 0;
  {
    RenderClient client = coordinator->Client();
    job = client.Submit(client.UploadScene(ExampleCornellBox(), true), s, 0, "kill-mid-reference");
    const v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus& x) { return x.passes_done() >= 2; }, 120);
    ASSERT_TRUE(st.state() == v1::JOB_STATE_RUNNING || st.state() == v1::JOB_STATE_PLANNING) << st.error();
    done_before = st.passes_done();
  }
  coordinator->process().Kill(SIGKILL);
  coordinator->process().Wait(5);
  ASSERT_LT(done_before, 4u) << "the job ended before the kill: make its passes longer";
  coordinator = std::make_unique<CoordinatorProcess>(dir, state, std::vector<std::string>{"--lease-timeout", "2"}, port);
  RenderClient client = coordinator->Client();
  const v1::JobStatus resumed = WaitForJob(client, job, [](const v1::JobStatus&) { return true; }, 30);
  EXPECT_GE(resumed.passes_done(), done_before) << "finished passes were lost";
  const v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 180);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  std::string exr, stats;
  client.Fetch(job, &exr, &stats);
  EXPECT_TRUE(SameBits(ExrImage(dir, "out.exr", exr), DirectAverage(31, 4, 6000, 32)));
  EXPECT_EQ(nlohmann::json::parse(stats)["passes"], 4);
}

TEST(Progressive, ARunningJobsResultIsItsPassesSoFarAndCancellingKeepsThem) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  auto worker = StartWorker(dir, coordinator.address());
  RenderSettings s = PassSettings(41, 300, 16);
  s.progressive.passes = 100000;
  RenderClient client = coordinator.Client();
  const std::string job = client.Submit(client.UploadScene(ExampleCornellBox(), true), s, 0, "endless");
  v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus& x) { return x.passes_done() >= 3; }, 120);
  // Between passes the job is planning its next one.
  ASSERT_TRUE(st.state() == v1::JOB_STATE_RUNNING || st.state() == v1::JOB_STATE_PLANNING) << st.error();
  EXPECT_TRUE(st.progressive());
  EXPECT_EQ(st.passes_total(), 100000u);
  EXPECT_GT(st.noise_rel_stderr(), 0.0);
  std::string exr, stats;
  client.Fetch(job, &exr, &stats);
  const int running_passes = nlohmann::json::parse(stats)["passes"].get<int>();
  EXPECT_GE(running_passes, 3);
  EXPECT_FALSE(nlohmann::json::parse(stats)["progressive"]["finished"].get<bool>());
  EXPECT_TRUE(SameBits(ExrImage(dir, "running.exr", exr), DirectAverage(41, uint32_t(running_passes), 300, 16)));

  // status names the pass, its noise and an ETA.
  const CliResult status = RunCli(dir, {"status", job, "--server", coordinator.address()});
  ASSERT_EQ(status.exit_code, 0) << status.err;
  EXPECT_NE(status.out.find("/100000"), std::string::npos) << status.out;
  EXPECT_NE(status.out.find("noise "), std::string::npos) << status.out;
  // watch --preview follows the mean of the finished passes; cancelled from another client.
  bool saw_mean_preview = false;
  RenderClient canceller = coordinator.Client();
  st = client.Watch(job, [&](const v1::JobStatus& x) {
    if (x.preview_png().empty() || x.preview_tiles() < (uint64_t(running_passes) << 32)) return;
    saw_mean_preview = true;
    canceller.Cancel(job);
  }, 60, 0.25);
  EXPECT_TRUE(saw_mean_preview);
  EXPECT_EQ(st.state(), v1::JOB_STATE_CANCELLED);
  client.Fetch(job, &exr, &stats);
  const int kept = nlohmann::json::parse(stats)["passes"].get<int>();
  EXPECT_GE(kept, running_passes);
  EXPECT_TRUE(SameBits(ExrImage(dir, "cancelled.exr", exr), DirectAverage(41, uint32_t(kept), 300, 16)));
}

// A job's scene is parsed once in a process: the embedded render's client parses it to list the
// files it uploads; the coordinator (every pass) and both workers take it from the cache.
TEST(Progressive, AnEmbeddedRenderParsesItsSceneOnce) {
  TempDir dir;
  const std::string scene = dir.Write("scene.pbrt", kTinyScene);
  const uint64_t parses = SceneCache::Process().parses(), hits = SceneCache::Process().hits();
  RenderSettings s;
  s.width = s.height = 8;
  s.lights = 50;
  s.progressive.passes = 3;
  const EmbeddedRender out = RenderOnEmbeddedFarm(scene, s, 2);
  EXPECT_EQ(out.stats["passes"], 3);
  EXPECT_EQ(SceneCache::Process().parses(), parses);
  // The coordinator plans each of the 3 passes, and a worker rebuilds each pass it runs.
  EXPECT_GE(SceneCache::Process().hits() - hits, 3u + 3u);
}

}  // namespace test_progressive_farm
}  // namespace lightfarm
