// What an operator relies on besides correctness: a cancelled job frees its workers at once (the
// running task is stopped, not run to its end), and TLS carries every RPC of workers and clients.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "common/render/render_job.h"
#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm_operations {

using namespace lightfarm::testing;

RenderSettings SmallJob() {
  RenderSettings s;
  s.width = s.height = 16;
  s.lights = 2000;
  s.seed = 11;
  s.params = {"rows_per_slice=64"};
  return s;
}

TEST(FarmOperations, CancellingAJobStopsItsRunningTaskOnTheWorker) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--lease-timeout", "2"});
  auto worker = StartWorker(dir, coordinator.address());
  RenderClient client = coordinator.Client();
  const v1::SceneManifest scene = client.UploadScene(ExampleCornellBox(), true);

  // One task of 128² receivers × 10^5 lights, brute force, on one thread: minutes of work.
  RenderSettings big;
  big.width = big.height = 128;
  big.lights = 100000;
  big.params = {"rows_per_slice=1000000"};
  const std::string long_job = client.Submit(scene, big, 0, "long");
  StateDb db(dir.Path("state") + "/state.sqlite");
  const auto leased = [&] {
    return db.Query("SELECT COUNT(*) FROM attempts WHERE ended IS NULL AND job_id = " + long_job)[0][0] > 0;
  };
  const auto wait_end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!leased() && std::chrono::steady_clock::now() < wait_end)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_TRUE(leased()) << "the long task was never leased";
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let the worker get into the gather
  EXPECT_EQ(client.Cancel(long_job).state(), v1::JOB_STATE_CANCELLED);

  // The only worker must be free for the next job long before the long task could have ended:
  // its task stops at the next heartbeat (a quarter of the lease timeout) and oneTBB chunk.
  const auto cancelled_at = std::chrono::steady_clock::now();
  const std::string next_job = client.Submit(scene, SmallJob(), 0, "next");
  const v1::JobStatus st = WaitForJob(client, next_job, [](const v1::JobStatus&) { return false; }, 120);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - cancelled_at).count();
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  // Running to the end would take ~10^5 · 128² ≈ 1.6·10^9 shadow rays on one thread (minutes).
  EXPECT_LT(seconds, 30.0) << "the worker kept running the cancelled task";
  EXPECT_TRUE(worker->running());
  EXPECT_EQ(client.GetJob(long_job).state(), v1::JOB_STATE_CANCELLED);
}

TEST(FarmOperations, WatchPreviewsShowMoreFinishedTilesAsTheJobRuns) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  auto worker = StartWorker(dir, coordinator.address());
  RenderClient client = coordinator.Client();
  RenderSettings s;
  s.width = s.height = 64;
  s.lights = 20000;
  s.params = {"rows_per_slice=64"};  // 64 tiles
  const std::string job = client.Submit(client.UploadScene(ExampleCornellBox(), true), s, 0, "preview");
  // The CLI keeps a PNG file updated while it follows the job.
  Process cli_watch({LIGHTFARM_CLI_PATH, "watch", job, "--server", coordinator.address(), "--preview",
                     dir.Path("w.png"), "--preview-interval", "0.25"},
                    dir.Path("cli-watch"));

  struct Seen {
    uint64_t tiles;
    size_t lit_pixels;
  };
  std::vector<Seen> previews;
  int index = 0;
  const v1::JobStatus last = client.Watch(job, [&](const v1::JobStatus& st) {
    if (st.preview_png().empty()) return;
    const std::string path = dir.Path("preview-" + std::to_string(index++) + ".png");
    std::ofstream(path, std::ios::binary) << st.preview_png();
    const Image img = ReadImage(path);
    EXPECT_EQ(img.width, 64);
    EXPECT_EQ(img.height, 64);
    EXPECT_EQ(st.preview_width(), 64u);
    EXPECT_LE(st.preview_tiles(), st.tasks_total());
    size_t lit = 0;
    for (const RGB& p : img.pixels) lit += p.r + p.g + p.b > 0;
    previews.push_back({st.preview_tiles(), lit});
  }, 300, 0.25);
  ASSERT_EQ(last.state(), v1::JOB_STATE_DONE) << last.error();
  ASSERT_GE(previews.size(), 2u) << "a 64-tile job on one worker thread sent fewer than two previews";
  for (size_t i = 1; i < previews.size(); ++i) {
    EXPECT_GT(previews[i].tiles, previews[i - 1].tiles);  // only newer previews are sent
    EXPECT_GE(previews[i].lit_pixels, previews[i - 1].lit_pixels);
  }
  EXPECT_LT(previews.front().lit_pixels, size_t(64 * 64));  // the first one is partial

  EXPECT_EQ(cli_watch.Wait(60), 0) << cli_watch.err();
  ASSERT_TRUE(std::filesystem::exists(dir.Path("w.png")));
  EXPECT_EQ(ReadImage(dir.Path("w.png")).width, 64);
  for (const std::filesystem::directory_entry& e : std::filesystem::directory_iterator(dir.Path("")))
    EXPECT_EQ(e.path().filename().string().find(".w.png.tmp"), std::string::npos) << "left " << e.path();
}

// Self-signed certificate for 127.0.0.1 made with the openssl command line tool.
void MakeCertificate(const TempDir& dir) {
  const std::string cmd = "openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=localhost"
                          " -addext subjectAltName=IP:127.0.0.1,DNS:localhost -keyout " +
                          dir.Path("key.pem") + " -out " + dir.Path("cert.pem") + " >" +
                          dir.Path("openssl.log") + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << Slurp(dir.Path("openssl.log"));
}

TEST(FarmOperations, TlsCarriesWorkersAndClientsAndRefusesPlaintext) {
  TempDir dir;
  MakeCertificate(dir);
  if (::testing::Test::HasFatalFailure()) return;
  CoordinatorProcess coordinator(dir, dir.Path("state"),
                                 {"--tls-cert", dir.Path("cert.pem"), "--tls-key", dir.Path("key.pem")});
  auto worker = StartWorker(dir, coordinator.address(), {"--tls-ca", dir.Path("cert.pem")});

  const std::vector<std::string> job = {"--resolution", "16x16", "--lights", "2000", "--seed", "11",
                                        "--param", "rows_per_slice=64", "--method", "brute"};
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator.address(), "--tls-ca",
                                     dir.Path("cert.pem"), "--wait", "--quiet", "--out", dir.Path("tls.exr")};
  submit.insert(submit.end(), job.begin(), job.end());
  CliResult r = RunCli(dir, submit);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const RenderOutput direct = RenderScene(ExampleCornellBox(), [] {
    RenderSettings s = SmallJob();
    s.method = "brute";
    return s;
  }());
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("tls.exr")), direct.image));

  // A plaintext client gets nowhere (the handshake fails: UNAVAILABLE), and the server is fine.
  RenderClient plain = coordinator.Client();
  try {
    plain.ListJobs();
    ADD_FAILURE() << "a plaintext client was served by a TLS coordinator";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::UNAVAILABLE) << e.what();
  }
  // A client that does not trust the certificate is refused too.
  std::vector<std::string> untrusted = {"status", "1", "--server", coordinator.address(), "--tls"};
  CliResult u = RunCli(dir, untrusted);
  EXPECT_NE(u.exit_code, 0);
  EXPECT_TRUE(coordinator.process().running());
}

// `submit --target-error`: the same choice as `render --target-error` from a bench's
// cost model, the predicted time printed before, the measured error after (the bench's cached
// reference), and the farm's image equal to the direct render's bits.
TEST(FarmOperations, SubmitWithTargetErrorUsesTheBenchAndReportsTheMeasuredError) {
  TempDir dir;
  const std::string scene = SourcePath("scenes/cornell-box/scene.pbrt");
  const std::vector<std::string> job = {"--resolution", "16x16", "--lights", "500", "--seed", "3"};
  // Without a truth: the target is a rel_l2 against same-lights brute force.
  std::vector<std::string> bench = {"bench", scene, "--out-dir", dir.Path("bench"), "--methods", "mrcs",
                                    "--repeats", "1", "--cache-dir", dir.Path("cache"), "--no-plots",
                                    "--lights", "500", "--resolution", "16x16", "--seed", "3", "--truth", "none"};
  CliResult b = RunCli(dir, bench, 300);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  auto with = [&](std::vector<std::string> head) {
    head.insert(head.end(), job.begin(), job.end());
    for (const char* a : {"--target-error", "0.05", "--method", "mrcs", "--quiet"}) head.push_back(a);
    for (const std::string& a : {std::string("--bench-dir"), dir.Path("bench"), std::string("--bench-cache"),
                                 dir.Path("cache")})
      head.push_back(a);
    return head;
  };
  CliResult direct = RunCli(dir, with({"render", scene, "--out", dir.Path("direct.exr")}));
  ASSERT_EQ(direct.exit_code, 0) << direct.err;

  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  auto worker = StartWorker(dir, coordinator.address());
  CliResult farm = RunCli(dir, with({"submit", scene, "--server", coordinator.address(), "--wait",
                                     "--out", dir.Path("farm.exr")}));
  ASSERT_EQ(farm.exit_code, 0) << farm.err;
  for (const CliResult* r : {&direct, &farm}) {
    EXPECT_NE(r->err.find("target error 0.05 (rel_l2 against same-lights brute force): mrcs"), std::string::npos)
        << r->err;
    EXPECT_NE(r->err.find("predicted time"), std::string::npos) << r->err;
    EXPECT_EQ(r->err.find("predicted time unknown"), std::string::npos) << r->err;
    EXPECT_NE(r->err.find("measured rel_l2"), std::string::npos) << r->err;
  }
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("farm.exr")), ReadImage(dir.Path("direct.exr"))));

  // Against a path-traced truth (lights and spp are part of the choice): the target is a truth
  // rel_l1, the method for `auto` is chosen too, and the error is measured against the truth.
  std::vector<std::string> truth_bench = {"bench", scene, "--out-dir", dir.Path("tbench"), "--methods", "lightcuts,path",
                                          "--repeats", "1", "--cache-dir", dir.Path("cache"), "--no-plots",
                                          "--lights", "300,1000", "--resolution", "16x16", "--seed", "3",
                                          "--truth", "path", "--truth-noise", "0.03"};
  CliResult tb = RunCli(dir, truth_bench, 300);
  ASSERT_EQ(tb.exit_code, 0) << tb.err;
  CliResult pick = RunCli(dir, {"render", scene, "--resolution", "16x16", "--seed", "3", "--quiet", "--target-error",
                                "0.5", "--bench-dir", dir.Path("tbench"), "--out", dir.Path("t.exr"), "--stats",
                                dir.Path("t.json")});
  ASSERT_EQ(pick.exit_code, 0) << pick.err;
  EXPECT_NE(pick.err.find("target error 0.5 (rel_l1 against the truth): "), std::string::npos) << pick.err;
  EXPECT_NE(pick.err.find("measured against the truth: rel_l1"), std::string::npos) << pick.err;
  const nlohmann::json stats = nlohmann::json::parse(Slurp(dir.Path("t.json")));
  EXPECT_EQ(stats["method_requested"], stats["method"]);  // resolved by the client, before the plan
  EXPECT_NE(stats["method_rule"].get<std::string>().find("bench against the truth"), std::string::npos);
  // `auto` without --target-error uses the same model (default 5% of the truth, or the
  // most accurate run when nothing reached it), from the cost model the bench cached.
  CliResult autop = RunCli(dir, {"render", scene, "--resolution", "16x16", "--seed", "3", "--quiet", "--bench-cache",
                                 dir.Path("cache"), "--out", dir.Path("a.exr"), "--stats", dir.Path("a.json")});
  ASSERT_EQ(autop.exit_code, 0) << autop.err;
  EXPECT_NE(autop.err.find("auto: bench against the truth"), std::string::npos) << autop.err;
  const nlohmann::json astats = nlohmann::json::parse(Slurp(dir.Path("a.json")));
  EXPECT_NE(astats["method_rule"].get<std::string>().find("bench against the truth"), std::string::npos);
}

}  // namespace test_farm_operations
}  // namespace lightfarm
