// The render farm as it runs: a coordinator process and worker processes on loopback, driven
// through the CLI and the client API. Farm, embedded and direct renders must be bit-identical;
// killed workers and coordinators must not lose or recompute finished work; bad input must get
// precise errors while the coordinator stays up.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <set>
#include <thread>

#include "cli/embedded_farm.h"
#include "common/receivers/receivers.h"
#include "common/render/render_job.h"
#include "tests/common/caustic_scene.h"
#include "tests/common/glossy_scene.h"
#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm {

using namespace lightfarm::testing;

// 32x32 Cornell box in ~16 slices of ~64 receivers against 20000 lights: a few seconds on two
// single-threaded workers, long enough to kill things mid-job.
// --method brute: the CLI's default is auto, JobSettings() keeps RenderSettings' brute.
const std::vector<std::string> kJobArgs = {"--method", "brute", "--resolution", "32x32", "--lights", "20000",
                                           "--seed", "7", "--param", "rows_per_slice=64"};

RenderSettings JobSettings() {
  RenderSettings s;
  s.width = s.height = 32;
  s.lights = 20000;
  s.seed = 7;
  s.params = {"rows_per_slice=64"};
  return s;
}

// The direct in-process render (RenderScene), computed once.
const RenderOutput& Direct() {
  static const RenderOutput out = RenderScene(ExampleCornellBox(), JobSettings());
  return out;
}
const Image& Reference() { return Direct().image; }
int ExpectedTasks() { return Direct().stats["tasks"].get<int>(); }

std::vector<std::string> Concat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

TEST(Farm, CliSubmitMatchesEmbeddedAndDirectRenderBitForBit) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  auto w1 = StartWorker(dir, coordinator.address());
  auto w2 = StartWorker(dir, coordinator.address());
  CliResult submit = RunCli(dir, Concat({"submit", ExampleCornellBox(), "--server", coordinator.address(), "--wait",
                                         "--quiet", "--out", dir.Path("farm.exr")},
                                        kJobArgs));
  ASSERT_EQ(submit.exit_code, 0) << submit.err;
  EXPECT_TRUE(std::filesystem::exists(dir.Path("farm.png")));
  nlohmann::json stats = nlohmann::json::parse(Slurp(dir.Path("farm.json")));
  EXPECT_EQ(stats["method"], "brute");
  EXPECT_EQ(stats["seed"], 7);
  EXPECT_EQ(stats["farm"]["tasks"], ExpectedTasks());

  CliResult embedded = RunCli(dir, Concat({"render", ExampleCornellBox(), "--workers", "2", "--quiet", "--out",
                                           dir.Path("embedded.exr"), "--stats", dir.Path("embedded.json")},
                                          kJobArgs));
  ASSERT_EQ(embedded.exit_code, 0) << embedded.err;
  const Image farm = ReadImage(dir.Path("farm.exr"));
  EXPECT_TRUE(SameBits(farm, ReadImage(dir.Path("embedded.exr"))));
  EXPECT_TRUE(SameBits(farm, Reference()));
  EXPECT_GT(farm.MeanLuminance(), 0.0);
  // The counters are the direct render's too (same tasks, summed in the same order).
  const nlohmann::json& direct = Direct().stats;
  EXPECT_EQ(stats["matrix"]["elements_evaluated"], direct["matrix"]["elements_evaluated"]);
  EXPECT_EQ(stats["rays"]["shadow"], direct["rays"]["shadow"]);

  // status / fetch / cancel of a finished job through the CLI.
  const std::string job = stats["farm"]["job_id"];
  CliResult status = RunCli(dir, {"status", job, "--server", coordinator.address()});
  EXPECT_EQ(status.exit_code, 0);
  EXPECT_NE(status.out.find("done"), std::string::npos) << status.out;
  CliResult fetch = RunCli(dir, {"fetch", job, "--server", coordinator.address(), "--out", dir.Path("again.exr")});
  ASSERT_EQ(fetch.exit_code, 0) << fetch.err;
  EXPECT_TRUE(SameBits(farm, ReadImage(dir.Path("again.exr"))));
  CliResult missing = RunCli(dir, {"status", "999", "--server", coordinator.address()});
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.err.find("NOT_FOUND"), std::string::npos) << missing.err;
}

// Every registered method, multi-stage ones included (stage artifacts combined on the
// coordinator), gives the direct render's bits on the embedded farm.
TEST(Farm, EveryMethodOnTheEmbeddedFarmMatchesTheDirectRender) {
  RenderSettings s;
  s.width = s.height = 16;
  s.lights = 600;
  s.seed = 11;
  s.params = {"rows_per_slice=48"};
  for (const std::string& method : GatherMethodNames()) {
    s.method = method;
    RenderOutput direct = RenderScene(ExampleCornellBox(), s);
    EmbeddedRender farm = RenderOnEmbeddedFarm(ExampleCornellBox(), s, 2);
    EXPECT_TRUE(SameBits(farm.image, direct.image)) << method;
    EXPECT_EQ(farm.stats["tasks"], direct.stats["tasks"]) << method;
    EXPECT_EQ(farm.stats["matrix"]["elements_evaluated"], direct.stats["matrix"]["elements_evaluated"]) << method;
  }
}

// A scene whose files are symbolic links to elsewhere (a shared asset library) renders as the
// real files do: the upload keeps each file where the scene names it.
TEST(Farm, SymlinkedSceneFilesRenderAsTheFilesThemselves) {
  TempDir real, linked;
  const std::string header = kTinyScene.substr(0, kTinyScene.size() - kQuad.size());
  real.Write("scene.pbrt", header + "Include \"geometry.pbrt\"\n");
  real.Write("geometry.pbrt", kQuad);
  linked.Write("scene.pbrt", header + "Include \"geometry.pbrt\"\n");
  std::filesystem::create_symlink(real.Path("geometry.pbrt"), linked.Path("geometry.pbrt"));
  RenderSettings s;
  s.lights = 50;
  const EmbeddedRender a = RenderOnEmbeddedFarm(real.Path("scene.pbrt"), s, 1);
  const EmbeddedRender b = RenderOnEmbeddedFarm(linked.Path("scene.pbrt"), s, 1);
  EXPECT_TRUE(SameBits(a.image, b.image));
  EXPECT_GT(a.image.MeanLuminance(), 0.0);
}

// Renders `scene` on a coordinator process with two worker processes (`lightfarm submit --wait`
// with `args`, written as NAME.exr and NAME.json in `dir`): the farm's image and stats.
struct FarmRender {
  Image image;
  nlohmann::json stats;
};
FarmRender SubmitToTwoWorkers(TempDir& dir, const std::string& scene, const std::string& name,
                              const std::vector<std::string>& args) {
  CoordinatorProcess coordinator(dir, dir.Path("state-" + name), {});
  auto w1 = StartWorker(dir, coordinator.address());
  auto w2 = StartWorker(dir, coordinator.address());
  CliResult submit = RunCli(dir, Concat({"submit", scene, "--server", coordinator.address(), "--wait", "--quiet",
                                         "--out", dir.Path(name + ".exr")},
                                        args));
  EXPECT_EQ(submit.exit_code, 0) << submit.err;
  if (submit.exit_code != 0) return {};
  return {ReadImage(dir.Path(name + ".exr")), nlohmann::json::parse(Slurp(dir.Path(name + ".json")))};
}

// The same, with the submit's options taken from the settings the direct render used (method,
// size, spp, lights, seed, params), so the two runs cannot drift apart.
FarmRender SubmitToTwoWorkers(TempDir& dir, const std::string& scene, const std::string& name,
                              const RenderSettings& s) {
  std::vector<std::string> args = {"--method", s.method, "--lights", std::to_string(s.lights), "--seed",
                                   std::to_string(s.seed)};
  if (s.width > 0) args.insert(args.end(), {"--resolution", std::to_string(s.width) + "x" + std::to_string(s.height)});
  if (s.spp > 0) args.insert(args.end(), {"--spp", std::to_string(s.spp)});
  for (const std::string& p : s.params) args.insert(args.end(), {"--param", p});
  return SubmitToTwoWorkers(dir, scene, name, args);
}

// A media scene through the whole pipeline on real processes: the cloud (NanoVDB density, VRLs,
// eye segments partitioned by METIS on the coordinator) gathered by adaptive-completion on two
// worker processes gives the direct render's bits, the clamp's compensation in the medium
// included (a distant light alone: on by default), and its stats show the media work.
TEST(Farm, MediaSceneOnWorkerProcessesMatchesTheDirectRenderBitForBit) {
  const std::string cloud = SourcePath("scenes/cloud/scene.pbrt");
  const std::vector<std::string> args = {"--method", "adaptive-completion", "--resolution", "24x24",
                                         "--lights", "400", "--seed", "5"};
  RenderSettings s;
  s.method = "adaptive-completion";
  s.width = s.height = 24;
  s.lights = 400;
  s.seed = 5;
  const RenderOutput direct = RenderScene(cloud, s);
  ASSERT_GT(direct.stats["lights"]["vrl"].get<double>(), 0);
  ASSERT_GT(direct.stats["receivers"]["segments"].get<double>(), 0);

  TempDir dir;
  const FarmRender farm = SubmitToTwoWorkers(dir, cloud, "cloud", args);
  EXPECT_TRUE(SameBits(farm.image, direct.image));
  EXPECT_GT(farm.image.MeanLuminance(), 0.0);
  const nlohmann::json& stats = farm.stats;
  EXPECT_EQ(stats["method"], "adaptive-completion");
  EXPECT_EQ(stats["lights"]["vrl"], direct.stats["lights"]["vrl"]);
  EXPECT_EQ(stats["receivers"]["segments"], direct.stats["receivers"]["segments"]);
  // The rows cover their pixels (coverage of eye segments, on by default): the pieces cross to
  // the workers with the rows.
  EXPECT_EQ(stats["receivers"]["segment_coverage"], kDefaultSegmentCoverage);
  EXPECT_GT(direct.stats["receivers"]["segment_pieces"].get<double>(), direct.stats["receivers"]["segments"].get<double>());
  EXPECT_EQ(stats["receivers"]["segment_pieces"], direct.stats["receivers"]["segment_pieces"]);
  EXPECT_EQ(stats["tasks"], direct.stats["tasks"]);
  EXPECT_EQ(stats["matrix"]["elements_evaluated"], direct.stats["matrix"]["elements_evaluated"]);
  EXPECT_GT(stats["matrix"]["transmittance_evals"].get<double>(), 0);
  EXPECT_EQ(stats["clamp"]["media_compensation"], true);
  EXPECT_GT(direct.stats["clamp"]["compensation_paths"].get<double>(), 0);
  EXPECT_EQ(stats["clamp"]["compensation_paths"], direct.stats["clamp"]["compensation_paths"]);
  const auto effects = stats["effects"].get<std::vector<std::string>>();
  EXPECT_NE(std::find(effects.begin(), effects.end(), "media"), effects.end());
}

// Caustic photons on worker processes: every worker traces the same photons from the job seed
// and gathers them on its rows (surfaces and eye segments), so the farm gives the direct
// render's bits.
TEST(Farm, CausticsOnWorkerProcessesMatchTheDirectRenderBitForBit) {
  TempDir dir;
  const std::string scene = dir.Write("beam.pbrt", SphereOverFloor(true, true));
  const std::vector<std::string> args = {"--method", "brute", "--resolution", "20x20", "--lights", "150",
                                         "--seed", "3", "--param", "caustic_photons=20000"};
  RenderSettings s;
  s.method = "brute";
  s.width = s.height = 20;
  s.lights = 150;
  s.seed = 3;
  s.params = {"caustic_photons=20000"};
  const RenderOutput direct = RenderScene(scene, s);
  ASSERT_GT(direct.stats["caustics"]["photons_used"].get<double>(), 0);

  const FarmRender farm = SubmitToTwoWorkers(dir, scene, "beam", args);
  EXPECT_TRUE(SameBits(farm.image, direct.image));
  EXPECT_EQ(farm.stats["caustics"]["photons_used"], direct.stats["caustics"]["photons_used"]);
  EXPECT_EQ(farm.stats["caustics"]["photons"], 20000);
}

// The sharp-lobe split on worker processes: each worker splits its scene's BSDFs as the plan
// did (the receivers and lights it receives were made with the split), so the farm gives the
// direct render's bits.
TEST(Farm, SharpLobesOnWorkerProcessesMatchTheDirectRenderBitForBit) {
  TempDir dir;
  const std::string scene = dir.Write("glossy.pbrt", GlossyPlane(0.02f));
  RenderSettings s;
  s.method = "lightcuts";
  s.width = 24;
  s.height = 16;
  s.lights = 300;
  s.seed = 4;
  s.params = {"caustic_photons=20000"};
  const RenderOutput direct = RenderScene(scene, s);
  ASSERT_EQ(direct.stats["sharp"]["materials"], 1);

  const FarmRender farm = SubmitToTwoWorkers(dir, scene, "glossy", s);
  EXPECT_TRUE(SameBits(farm.image, direct.image));
  EXPECT_EQ(farm.stats["sharp"], direct.stats["sharp"]);
}

// The element bound and its traced compensation (a tight bsdf_clamp on a rough mirror whose
// lobe the split leaves to the VPLs) on worker processes: the direct render's bits and counters.
TEST(Farm, ElementBoundOnWorkerProcessesMatchesTheDirectRenderBitForBit) {
  TempDir dir;
  const std::string scene = dir.Write("glossy.pbrt", GlossyPlane(0.02f));
  RenderSettings s;
  s.method = "mrcs";
  s.width = 24;
  s.height = 16;
  s.lights = 300;
  s.seed = 4;
  s.params = {"sharp_roughness=0", "bsdf_clamp=0.1", "caustic_photons=20000"};
  const RenderOutput direct = RenderScene(scene, s);
  ASSERT_GT(direct.stats["clamp"]["bound_elements"].get<double>(), 0);

  const FarmRender farm = SubmitToTwoWorkers(dir, scene, "bound", s);
  EXPECT_TRUE(SameBits(farm.image, direct.image));
  EXPECT_EQ(farm.stats["clamp"], direct.stats["clamp"]);
}

// Split mixed vertices (a clear coat over a grey base): several receivers per camera sample,
// shipped to the workers in the receiver set and summed per sample, give the direct render's bits.
TEST(Farm, SplitCoatVerticesOnWorkerProcessesMatchTheDirectRenderBitForBit) {
  TempDir dir;
  const std::string scene = dir.Write("coated.pbrt", testing::CoatedPlane(0.001f));
  RenderSettings s;
  s.method = "lightcuts";
  s.width = 24;
  s.height = 16;
  s.lights = 300;
  s.seed = 6;
  s.spp = 2;
  s.params = {"splits=2"};
  const RenderOutput direct = RenderScene(scene, s);
  ASSERT_GT(direct.stats["receivers"]["points_per_sample"].get<double>(), 1.0);

  const FarmRender farm = SubmitToTwoWorkers(dir, scene, "coated", s);
  EXPECT_TRUE(SameBits(farm.image, direct.image));
  EXPECT_EQ(farm.stats["receivers"], direct.stats["receivers"]);
}

// The path tracer on worker processes: tiles × sample passes, the passes of a pixel summed in
// task order, give the direct render's bits (the cloud: NanoVDB density, delta and ratio tracking).
TEST(Farm, PathTracedMediaSceneOnWorkerProcessesMatchesTheDirectRenderBitForBit) {
  const std::string cloud = SourcePath("scenes/cloud/scene.pbrt");
  const std::vector<std::string> args = {"--method", "path", "--resolution", "24x24", "--spp", "12", "--seed", "5",
                                         "--param", "tile=8", "--param", "pass_spp=5"};
  RenderSettings s;
  s.method = "path";
  s.width = s.height = 24;
  s.spp = 12;
  s.seed = 5;
  s.params = {"tile=8", "pass_spp=5"};
  const RenderOutput direct = RenderScene(cloud, s);
  EXPECT_EQ(direct.stats["tasks"], 9 * 3);

  TempDir dir;
  const FarmRender farm = SubmitToTwoWorkers(dir, cloud, "cloud", args);
  EXPECT_TRUE(SameBits(farm.image, direct.image));
  EXPECT_GT(farm.image.MeanLuminance(), 0.0);
  const nlohmann::json& stats = farm.stats;
  EXPECT_EQ(stats["method"], "path");
  EXPECT_EQ(stats["spp"], 12);
  EXPECT_EQ(stats["rays"]["shadow"], direct.stats["rays"]["shadow"]);
  EXPECT_EQ(stats["rays"]["camera"], 24 * 24 * 12);
}

// The shared libraries a live process has mapped.
std::string MappedFiles(pid_t pid) { return Slurp("/proc/" + std::to_string(pid) + "/maps"); }

// OpenImageIO (~300 libraries, half a second per process start) is a module loaded only where
// images are read or written (common/image/image_io_backend.h): the coordinator, which writes
// every job's EXR and checks for the module at start, and never a worker on a scene without
// image textures.
TEST(Farm, OnlyTheCoordinatorLoadsTheImageLibraries) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  auto worker = StartWorker(dir, coordinator.address());
  RenderClient client = coordinator.Client();
  RenderSettings s = JobSettings();
  s.lights = 2000;
  const std::string job = client.Submit(client.UploadScene(ExampleCornellBox(), true), s, 0, "maps");
  const v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  EXPECT_EQ(MappedFiles(worker->pid()).find("libOpenImageIO"), std::string::npos);
  EXPECT_NE(MappedFiles(coordinator.process().pid()).find("libOpenImageIO"), std::string::npos);
  EXPECT_NE(MappedFiles(coordinator.process().pid()).find("liblightfarm_imageio.so"), std::string::npos);
}

TEST(Farm, KilledWorkerIsReplacedWithinOneLeaseTimeout) {
  TempDir dir;
  const double lease = 1.5;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--lease-timeout", "1.5"});
  auto w1 = StartWorker(dir, coordinator.address());
  auto w2 = StartWorker(dir, coordinator.address());
  RenderClient client = coordinator.Client();
  const std::string job = client.Submit(client.UploadScene(ExampleCornellBox(), true), JobSettings(), 0, "kill-worker");
  v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.tasks_done() >= 2; }, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_RUNNING) << st.error();
  // Kill the worker that holds a lease right now.
  StateDb db(dir.Path("state") + "/state.sqlite");
  const std::string open_attempt = "SELECT a.id, w.name FROM attempts a JOIN workers w ON a.worker_id = w.id "
                                   "WHERE a.ended IS NULL AND a.job_id = " + job + " ORDER BY a.id LIMIT 1";
  const std::string attempt = db.QueryText("SELECT CAST(id AS TEXT) FROM (" + open_attempt + ")");
  const std::string holder = db.QueryText("SELECT name FROM (" + open_attempt + ")");
  ASSERT_FALSE(attempt.empty());
  Process* victim = holder == w1->name ? w1.get() : w2.get();
  Process* survivor = victim == w1.get() ? w2.get() : w1.get();
  const auto killed_at = std::chrono::steady_clock::now();
  const int64_t kill_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                              std::chrono::system_clock::now().time_since_epoch()).count();
  victim->Kill(SIGKILL);
  victim->Wait(5);
  st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 120);
  const double after_kill = std::chrono::duration<double>(std::chrono::steady_clock::now() - killed_at).count();
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  std::string exr, stats;
  client.Fetch(job, &exr, &stats);
  std::ofstream(dir.Path("out.exr"), std::ios::binary) << exr;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("out.exr")), Reference()));
  // The killed worker's lease expired no later than one lease timeout (plus the coordinator's
  // check period) after the kill, and its task was then done again by the survivor. (If the
  // task finished in the instant before the kill, there is nothing to expire.)
  const std::string outcome = db.QueryText("SELECT outcome FROM attempts WHERE id = " + attempt);
  if (outcome != "done") {
    EXPECT_EQ(outcome, "expired");
    auto ended = db.Query("SELECT CAST(ended * 1000 AS INTEGER), task_id FROM attempts WHERE id = " + attempt);
    EXPECT_LE(ended[0][0] - kill_ms, int64_t((lease + 0.5) * 1000)) << "lease expired late";
    auto redone = db.Query("SELECT COUNT(*) FROM attempts WHERE job_id = " + job + " AND task_id = " +
                           std::to_string(ended[0][1]) + " AND outcome = 'done'");
    EXPECT_EQ(redone[0][0], 1);
  }
  EXPECT_EQ(db.Query("SELECT COUNT(*) FROM tasks WHERE state = 2 AND job_id = " + job)[0][0], ExpectedTasks());
  EXPECT_LT(after_kill, lease + 60.0);
  EXPECT_TRUE(survivor->running());
}

TEST(Farm, KilledCoordinatorResumesWithoutRecomputingFinishedTasks) {
  TempDir dir;
  const std::string state = dir.Path("state");
  auto coordinator = std::make_unique<CoordinatorProcess>(dir, state, std::vector<std::string>{"--lease-timeout", "2"});
  const int port = coordinator->port();
  const std::string address = coordinator->address();
  auto w1 = StartWorker(dir, address);
  auto w2 = StartWorker(dir, address);
  std::string job;
  {
    RenderClient client = coordinator->Client();
    job = client.Submit(client.UploadScene(ExampleCornellBox(), true), JobSettings(), 0, "kill-coordinator");
    v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.tasks_done() >= 4; }, 60);
    ASSERT_EQ(st.state(), v1::JOB_STATE_RUNNING) << st.error();
  }
  // Tasks finished (and acknowledged) before the kill.
  std::vector<std::vector<int64_t>> done_before;
  {
    StateDb db(state + "/state.sqlite");
    done_before = db.Query("SELECT task_id FROM tasks WHERE state = 2 AND job_id = " + job);
  }
  coordinator->process().Kill(SIGKILL);
  coordinator->process().Wait(5);
  ASSERT_GE(done_before.size(), 4u);
  ASSERT_LT(done_before.size(), size_t(ExpectedTasks()));
  coordinator = std::make_unique<CoordinatorProcess>(dir, state, std::vector<std::string>{"--lease-timeout", "2"}, port);
  RenderClient client = coordinator->Client();
  v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  std::string exr, stats;
  client.Fetch(job, &exr, &stats);
  std::ofstream(dir.Path("out.exr"), std::ios::binary) << exr;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("out.exr")), Reference()));
  StateDb db(state + "/state.sqlite");
  for (const auto& row : done_before) {
    auto attempts = db.Query("SELECT COUNT(*) FROM attempts WHERE job_id = " + job +
                             " AND task_id = " + std::to_string(row[0]));
    EXPECT_EQ(attempts[0][0], 1) << "task " << row[0] << " was recomputed after the restart";
  }
  EXPECT_EQ(nlohmann::json::parse(stats)["farm"]["tasks"], ExpectedTasks());
}

// A worker killed while it prepared a task leaves a half-materialized scene directory in its
// cache; a worker started later on the same cache (a Slurm array element with the same index, a
// restarted pod with a persistent volume) must clear it and run tasks, not fail each one.
TEST(Farm, AWorkerOnTheCacheOfAKilledWorkerRunsTasks) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  const std::string cache = dir.Path("reused-cache");
  // The worker's temporary names are a counter: leave every name its first task would use.
  for (int k = 0; k < 8; ++k) {
    const std::string left = cache + "/blobs/tmp/" + std::to_string(k) + "-scene";
    std::filesystem::create_directories(left + "/meshes");
    std::ofstream(left + "/scene.pbrt") << "left by a killed worker";
    std::ofstream(left + "/tiny.pbrt") << "left by a killed worker";
  }
  std::ofstream(cache + "/blobs/tmp/0") << "a partial blob";
  Process worker({LIGHTFARM_WORKER_PATH, "--coordinator", coordinator.address(), "--threads", "1", "--poll-interval",
                  "0.02", "--cache-dir", cache, "--log-level", "warn"},
                 dir.Path("reused-worker"));
  const std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  CliResult ok = RunCli(dir, {"submit", scene, "--server", coordinator.address(), "--wait", "--quiet", "--lights",
                              "10", "--out", dir.Path("tiny.exr")});
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_FALSE(std::filesystem::exists(cache + "/blobs/tmp/7-scene/scene.pbrt"));
}

TEST(Farm, AuthenticationIsRequiredOnEveryRpc) {
  TempDir dir;
  const std::string token = dir.Write("token", "s3cret-token\n");
  const std::string wrong = dir.Write("wrong", "not-the-token\n");
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--token-file", token});
  CliResult none = RunCli(dir, {"status", "--server", coordinator.address()});
  EXPECT_NE(none.exit_code, 0);
  EXPECT_NE(none.err.find("UNAUTHENTICATED"), std::string::npos) << none.err;
  CliResult bad = RunCli(dir, {"submit", ExampleCornellBox(), "--server", coordinator.address(), "--token-file", wrong});
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("UNAUTHENTICATED"), std::string::npos) << bad.err;
  // A worker with the wrong token is refused for good.
  auto worker = StartWorker(dir, coordinator.address(), {"--token-file", wrong});
  EXPECT_EQ(worker->Wait(20), 3) << worker->err();
  EXPECT_NE(worker->err().find("UNAUTHENTICATED"), std::string::npos) << worker->err();
  // With the token everything works.
  auto good_worker = StartWorker(dir, coordinator.address(), {"--token-file", token});
  const std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  CliResult ok = RunCli(dir, {"submit", scene, "--server", coordinator.address(), "--token-file", token, "--wait",
                              "--quiet", "--lights", "10", "--out", dir.Path("tiny.exr")});
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
}

TEST(Farm, BadInputGetsPreciseErrorsAndTheCoordinatorStaysUp) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--max-blob-mb", "0.01"});
  auto worker = StartWorker(dir, coordinator.address());
  // A malformed scene fails its job, naming file:line.
  const std::string bad = dir.Write("bad.pbrt", "Film \"rgb\"\nWorldBegin\nShape \"trianglemesh\" \"point3 P\" [ 1 2\n");
  CliResult r = RunCli(dir, {"submit", bad, "--server", coordinator.address(), "--wait", "--quiet"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("failed"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("bad.pbrt:"), std::string::npos) << r.err;
  // An oversized blob is refused with RESOURCE_EXHAUSTED.
  RenderClient client = coordinator.Client();
  try {
    client.UploadBlob(std::string(64 * 1024, 'x'));
    ADD_FAILURE() << "a 64 KiB blob passed a 10 KiB limit";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << e.what();
  }
  // Unknown method, unknown job, blobs never uploaded.
  v1::SceneManifest manifest;
  manifest.set_root("x.pbrt");
  auto* f = manifest.add_files();
  f->set_path("x.pbrt");
  f->set_sha256(std::string(64, 'a'));
  try {
    client.Submit(manifest, RenderSettings{}, 0, "");
    ADD_FAILURE() << "a job with a missing blob was accepted";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::FAILED_PRECONDITION) << e.what();
  }
  f->set_path("../../etc/passwd");
  EXPECT_THROW(client.Submit(manifest, RenderSettings{}, 0, ""), RpcError);
  EXPECT_THROW(client.GetJob("nope"), RpcError);
  // Still healthy: a good job completes.
  const std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  CliResult ok = RunCli(dir, {"submit", scene, "--server", coordinator.address(), "--wait", "--quiet",
                              "--lights", "10", "--out", dir.Path("tiny.exr")});
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_TRUE(coordinator.process().running());
  EXPECT_TRUE(HealthServing(coordinator.address()));
}

TEST(Farm, OldVersionWorkerIsRefused) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  auto old = StartWorker(dir, coordinator.address(), {"--protocol-version", "0"});
  EXPECT_EQ(old->Wait(20), 3);
  const std::string err = old->err();
  EXPECT_NE(err.find("FAILED_PRECONDITION"), std::string::npos) << err;
  EXPECT_NE(err.find("protocol 0"), std::string::npos) << err;
  EXPECT_NE(err.find("upgrade"), std::string::npos) << err;
}

TEST(Farm, FiftyConcurrentSubmissionsAllCompleteOnce) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--max-active-jobs", "4"});
  auto w1 = StartWorker(dir, coordinator.address());
  auto w2 = StartWorker(dir, coordinator.address());
  const std::string scene = dir.Write("tiny.pbrt", kTinyScene);
  RenderSettings s;
  s.lights = 10;
  s.seed = 3;
  constexpr int kJobs = 50;
  std::vector<std::string> ids(kJobs);
  std::atomic<int> errors{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < kJobs; ++i)
    threads.emplace_back([&, i] {
      try {
        RenderClient client = coordinator.Client();
        ids[size_t(i)] = client.Submit(client.UploadScene(scene, true), s, i % 3, "job" + std::to_string(i));
      } catch (const std::exception& e) {
        ++errors;
        ADD_FAILURE() << e.what();
      }
    });
  for (std::thread& t : threads) t.join();
  ASSERT_EQ(errors, 0);
  EXPECT_EQ(std::set<std::string>(ids.begin(), ids.end()).size(), size_t(kJobs));
  RenderClient client = coordinator.Client();
  Image first;
  for (const std::string& id : ids) {
    v1::JobStatus st = WaitForJob(client, id, [](const v1::JobStatus&) { return false; }, 120);
    ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << id << ": " << st.error();
    EXPECT_EQ(st.tasks_completed_total(), 1u) << id;
    std::string exr, stats;
    client.Fetch(id, &exr, &stats);
    EXPECT_EQ(nlohmann::json::parse(stats)["farm"]["job_id"], id);
    // Same pixels (the EXR header carries the file's creation time, so bytes may differ).
    std::ofstream(dir.Path("job.exr"), std::ios::binary) << exr;
    Image image = ReadImage(dir.Path("job.exr"));
    if (first.Empty()) first = image;
    EXPECT_TRUE(SameBits(image, first)) << id;
  }
  EXPECT_EQ(client.ListJobs().size(), size_t(kJobs));
}

}  // namespace test_farm
}  // namespace lightfarm
