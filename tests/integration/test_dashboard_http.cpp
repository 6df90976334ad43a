// The coordinator's HTTP side (--http-listen) as a client sees it: auth by bearer header or the
// login cookie, precise statuses for bad requests, escaping of what users typed, and the JSON API
// agreeing with the gRPC one (workers, priority). The browser test (tests/browser) drives the page.
#include <gtest/gtest.h>
#include <httplib.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "common/render/render_job.h"
#include "coordinator/dashboard.h"
#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_dashboard_http {

using namespace lightfarm::testing;
using json = nlohmann::json;

const std::string kToken = "http-test-token";

struct Farm {
  TempDir dir;
  std::unique_ptr<CoordinatorProcess> coordinator;
  int http_port = 0;

  explicit Farm(std::vector<std::string> extra = {}) {
    std::ofstream(dir.Path("token")) << kToken << "\n";
    std::vector<std::string> args = {"--token-file", dir.Path("token"), "--http-listen", "127.0.0.1:0"};
    args.insert(args.end(), extra.begin(), extra.end());
    coordinator = std::make_unique<CoordinatorProcess>(dir, dir.Path("state"), args);
    const std::string out = coordinator->process().out();
    const size_t at = out.find("dashboard on port ");
    if (at == std::string::npos) {
      ADD_FAILURE() << "no dashboard port in: " << out;
      return;
    }
    http_port = std::stoi(out.substr(at + 18));
  }
  httplib::Client Http() const {
    httplib::Client c("127.0.0.1", http_port);
    c.set_connection_timeout(10);
    c.set_read_timeout(30);
    return c;
  }
  static httplib::Headers Bearer(const std::string& token = kToken) {
    return {{"Authorization", "Bearer " + token}};
  }
};

RenderSettings Small() {
  RenderSettings s;
  s.width = s.height = 16;
  s.lights = 300;
  return s;
}

TEST(DashboardHttp, EveryRequestNeedsTheTokenAsABearerHeaderOrTheLoginCookie) {
  Farm farm;
  httplib::Client http = farm.Http();
  EXPECT_EQ(http.Get("/api/v1/jobs")->status, 401);
  EXPECT_EQ(http.Get("/api/v1/jobs", Farm::Bearer("wrong"))->status, 401);
  EXPECT_EQ(http.Get("/metrics")->status, 401);
  EXPECT_EQ(http.Get("/api/v1/jobs", Farm::Bearer())->status, 200);
  EXPECT_EQ(http.Get("/metrics", Farm::Bearer())->status, 200);
  // A page without the token sends the browser to the login form.
  auto page = http.Get("/");
  EXPECT_EQ(page->status, 303);
  EXPECT_EQ(page->get_header_value("Location"), "/login");

  // The form: a wrong token is refused, the right one sets an HttpOnly cookie, which then works
  // and holds a hash of the token, not the token.
  auto wrong = http.Post("/login", "token=nope", "application/x-www-form-urlencoded");
  EXPECT_EQ(wrong->status, 303);
  EXPECT_EQ(wrong->get_header_value("Location"), "/login?error=wrong+token");
  EXPECT_FALSE(wrong->has_header("Set-Cookie"));
  auto right = http.Post("/login", "token=" + kToken, "application/x-www-form-urlencoded");
  ASSERT_EQ(right->status, 303);
  const std::string cookie = right->get_header_value("Set-Cookie");
  EXPECT_NE(cookie.find("HttpOnly"), std::string::npos) << cookie;
  EXPECT_NE(cookie.find("SameSite=Strict"), std::string::npos) << cookie;
  EXPECT_EQ(cookie.find(kToken), std::string::npos) << "the cookie must not carry the token itself";
  const std::string pair = cookie.substr(0, cookie.find(';'));
  EXPECT_EQ(http.Get("/api/v1/jobs", {{"Cookie", pair}})->status, 200);
  EXPECT_EQ(http.Get("/api/v1/jobs", {{"Cookie", "lightfarm_session=forged"}})->status, 401);
  EXPECT_EQ(http.Get("/", {{"Cookie", pair}})->status, 200);
}

TEST(DashboardHttp, WhatUsersTypedComesBackEscaped) {
  Farm farm;
  httplib::Client http = farm.Http();
  auto login = http.Get("/login?error=%3Cscript%3Ealert(1)%3C%2Fscript%3E");
  ASSERT_EQ(login->status, 200);
  EXPECT_EQ(login->body.find("<script>alert(1)"), std::string::npos);
  EXPECT_NE(login->body.find("&lt;script&gt;alert(1)&lt;/script&gt;"), std::string::npos);
  EXPECT_EQ(HtmlEscape("<a href=\"x\">'&'</a>"), "&lt;a href=&quot;x&quot;&gt;&#39;&amp;&#39;&lt;/a&gt;");

  // A job name with markup: the JSON carries it as text.
  RenderClient client = farm.coordinator->Client(kToken);
  const v1::SceneManifest scene = client.UploadScene(ExampleCornellBox(), true);
  const std::string id = client.Submit(scene, Small(), 0, "<img src=x onerror=alert(1)>");
  auto jobs = http.Get("/api/v1/jobs", Farm::Bearer());
  ASSERT_EQ(jobs->status, 200);
  const json j = json::parse(jobs->body);
  ASSERT_EQ(j["jobs"].size(), 1u);
  EXPECT_EQ(j["jobs"][0]["id"], id);
  EXPECT_EQ(j["jobs"][0]["name"], "<img src=x onerror=alert(1)>");
  // The page is one static shell: no user text is ever put into HTML by the server.
  auto page = http.Get("/jobs/" + id, Farm::Bearer());
  ASSERT_EQ(page->status, 200);
  EXPECT_EQ(page->body.find("onerror"), std::string::npos);
  EXPECT_NE(page->get_header_value("Content-Security-Policy").find("script-src 'self'"), std::string::npos);
}

TEST(DashboardHttp, BadRequestsGetPreciseStatusesAndTheApiMatchesTheRpcs) {
  Farm farm;
  auto worker = StartWorker(farm.dir, farm.coordinator->address(), {"--token-file", farm.dir.Path("token")});
  httplib::Client http = farm.Http();
  RenderClient client = farm.coordinator->Client(kToken);
  const v1::SceneManifest scene = client.UploadScene(ExampleCornellBox(), true);
  const std::string done = client.Submit(scene, Small(), 0, "done");
  ASSERT_EQ(WaitForJob(client, done, [](const v1::JobStatus&) { return false; }, 60).state(), v1::JOB_STATE_DONE);

  // Job detail: stats, the PNG of the result, the EXR.
  auto detail = http.Get("/api/v1/jobs/" + done, Farm::Bearer());
  ASSERT_EQ(detail->status, 200);
  const json d = json::parse(detail->body);
  EXPECT_EQ(d["state"], "done");
  EXPECT_EQ(d["stats"]["method"], "brute");
  EXPECT_EQ(d["scene_sha256"].get<std::string>().size(), 64u);
  auto png = http.Get("/api/v1/jobs/" + done + "/image.png", Farm::Bearer());
  ASSERT_EQ(png->status, 200);
  EXPECT_EQ(png->body.substr(1, 3), "PNG");
  auto exr = http.Get("/api/v1/jobs/" + done + "/result.exr", Farm::Bearer());
  ASSERT_EQ(exr->status, 200);
  EXPECT_EQ(exr->body.substr(0, 4), std::string("\x76\x2f\x31\x01", 4));
  EXPECT_NE(exr->get_header_value("Content-Disposition").find("attachment"), std::string::npos);

  const httplib::Headers intent = {{"Authorization", "Bearer " + kToken}, {"X-Lightfarm-Request", "1"}};
  EXPECT_EQ(http.Get("/api/v1/jobs/999", Farm::Bearer())->status, 404);
  EXPECT_EQ(http.Get("/api/v1/jobs/999/image.png", Farm::Bearer())->status, 404);
  EXPECT_EQ(http.Get("/api/v1/nothing", Farm::Bearer())->status, 404);
  // POST without the intent header (a cross-site form could send the cookie): refused.
  EXPECT_EQ(http.Post("/api/v1/jobs/" + done + "/cancel", Farm::Bearer(), "", "application/json")->status, 403);
  EXPECT_EQ(http.Post("/api/v1/jobs/" + done + "/priority", intent, "{\"priority\": \"high\"}", "application/json")->status, 400);
  EXPECT_EQ(http.Post("/api/v1/jobs/" + done + "/priority", intent, "not json", "application/json")->status, 400);
  EXPECT_EQ(http.Post("/api/v1/jobs/" + done + "/priority", intent, "{\"priority\": 99999999999}", "application/json")->status, 400);
  auto ended = http.Post("/api/v1/jobs/" + done + "/priority", intent, "{\"priority\": 3}", "application/json");
  EXPECT_EQ(ended->status, 409);
  EXPECT_NE(json::parse(ended->body)["error"].get<std::string>().find("done"), std::string::npos);

  // A long job on the only worker, a second one queued behind it: priority through HTTP is what
  // the gRPC API reports; cancel through HTTP ends it.
  RenderSettings big = Small();
  big.width = big.height = 128;
  big.lights = 50000;
  const std::string running = client.Submit(scene, big, 0, "long");
  const std::string queued = client.Submit(scene, Small(), 0, "queued");
  auto raised = http.Post("/api/v1/jobs/" + queued + "/priority", intent, "{\"priority\": 5}", "application/json");
  ASSERT_EQ(raised->status, 200) << raised->body;
  EXPECT_EQ(json::parse(raised->body)["priority"], 5);
  EXPECT_EQ(client.GetJob(queued).priority(), 5);
  EXPECT_EQ(client.SetPriority(queued, -2).priority(), -2);
  EXPECT_EQ(json::parse(http.Get("/api/v1/jobs/" + queued, Farm::Bearer())->body)["priority"], -2);

  // Workers: the one worker, its finished tasks, the task it holds now.
  WaitForJob(client, running, [](const v1::JobStatus& s) { return s.attempts() > 0; }, 60);
  const auto holds_task = [&] {
    for (const v1::WorkerStatus& w : client.ListWorkers())
      if (w.job_id() == running) return true;
    return false;
  };
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!holds_task() && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  auto workers = http.Get("/api/v1/workers", Farm::Bearer());
  ASSERT_EQ(workers->status, 200);
  const json w = json::parse(workers->body)["workers"];
  ASSERT_EQ(w.size(), 1u) << w.dump();
  EXPECT_EQ(w[0]["name"], worker->name);
  EXPECT_EQ(w[0]["threads"], 1);
  EXPECT_TRUE(w[0]["alive"].get<bool>());
  EXPECT_GE(w[0]["tasks_done"].get<int>(), 1);
  EXPECT_EQ(w[0]["job_id"], running);

  auto cancelled = http.Post("/api/v1/jobs/" + running + "/cancel", intent, "", "application/json");
  ASSERT_EQ(cancelled->status, 200);
  EXPECT_EQ(json::parse(cancelled->body)["state"], "cancelled");
  EXPECT_EQ(client.GetJob(running).state(), v1::JOB_STATE_CANCELLED);
}

TEST(DashboardHttp, WithoutATokenItServesLoopbackOnly) {
  TempDir dir;
  Process refused({LIGHTFARM_COORDINATOR_PATH, "--listen", "127.0.0.1:0", "--state-dir", dir.Path("state"),
                   "--http-listen", "0.0.0.0:0"},
                  dir.Path("refused"));
  EXPECT_NE(refused.Wait(30), 0);
  EXPECT_NE(refused.err().find("loopback"), std::string::npos) << refused.err();

  // PORT alone binds 127.0.0.1; no token: no auth asked.
  CoordinatorProcess open(dir, dir.Path("state2"), {"--http-listen", "0"});
  const std::string out = open.process().out();
  ASSERT_NE(out.find("dashboard on port "), std::string::npos) << out;
  httplib::Client http("127.0.0.1", std::stoi(out.substr(out.find("dashboard on port ") + 18)));
  EXPECT_EQ(http.Get("/api/v1/jobs")->status, 200);
  EXPECT_EQ(http.Get("/")->status, 200);
}

}  // namespace test_dashboard_http
}  // namespace lightfarm
