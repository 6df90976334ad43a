// Trust no worker blindly: a fake worker process that speaks the worker protocol and lies (wrong
// numbers of the right shape, NaN, or failures) beside honest workers. Verified tasks outvote
// it and it is blocklisted farm-wide; NaN results are refused; a job that no live worker may run
// fails saying why instead of running forever; a lease lost to a stall is not held against the
// worker.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm_verification {

using namespace lightfarm::testing;

const std::vector<std::string> kJob = {"--method", "brute", "--resolution", "16x16", "--lights", "500",
                                       "--seed", "9", "--param", "rows_per_slice=32"};

std::unique_ptr<Process> StartLiar(const TempDir& dir, const std::string& address, const std::string& mode,
                                   std::vector<std::string> extra = {}) {
  std::vector<std::string> argv = {LIGHTFARM_LYING_WORKER_PATH, "--coordinator", address, "--mode", mode,
                                   "--name", "liar-" + mode};
  argv.insert(argv.end(), extra.begin(), extra.end());
  auto p = std::make_unique<Process>(argv, dir.Path("liar-" + mode));
  p->name = "liar-" + mode;
  return p;
}

Image Embedded(const TempDir& dir) {
  std::vector<std::string> args = {"render", ExampleCornellBox(), "--quiet", "--out", dir.Path("embedded.exr")};
  args.insert(args.end(), kJob.begin(), kJob.end());
  CliResult r = RunCli(dir, args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return ReadImage(dir.Path("embedded.exr"));
}

// Waits until the liar has registered (so it competes for the first tasks).
void WaitForWorkers(RenderClient& client, size_t n) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (client.ListWorkers().size() < n && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
}

// A job submitted with --verify: every task runs on two workers; where the liar's result
// differs, a third worker decides. The image is the embedded render's, every task is verified,
// and the liar is blocklisted (it can lease nothing more).
TEST(FarmVerification, ALyingWorkerIsOutvotedAndBlocklisted) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  RenderClient client = coordinator.Client();
  auto liar = StartLiar(dir, coordinator.address(), "wrong");
  WaitForWorkers(client, 1);
  auto honest_a = StartWorker(dir, coordinator.address());
  auto honest_b = StartWorker(dir, coordinator.address());
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator.address(), "--wait",
                                     "--quiet", "--verify", "--out", dir.Path("farm.exr")};
  submit.insert(submit.end(), kJob.begin(), kJob.end());
  CliResult r = RunCli(dir, submit);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("farm.exr")), Embedded(dir)));

  const std::string job = nlohmann::json::parse(Slurp(dir.Path("farm.json")))["farm"]["job_id"];
  const v1::JobStatus st = client.GetJob(job);
  EXPECT_GE(st.tasks_total(), 4u);
  EXPECT_EQ(st.tasks_verified(), st.tasks_total());
  bool liar_seen = false;
  for (const v1::WorkerStatus& w : client.ListWorkers()) {
    if (w.name() == "liar-wrong") {
      liar_seen = true;
      EXPECT_NE(w.blocklisted().find("differed from two other workers"), std::string::npos) << w.DebugString();
    } else {
      EXPECT_TRUE(w.blocklisted().empty()) << w.DebugString();
    }
  }
  EXPECT_TRUE(liar_seen);
  EXPECT_NE(liar->out().find("blocklisted"), std::string::npos) << liar->out();
  const std::string log = coordinator.process().err();
  EXPECT_NE(log.find("is blocklisted"), std::string::npos) << log;
}

// Without verification a liar's wrong numbers could pass; NaN never does: the result is refused
// as the task's failure, the liar is kept off the job, and an honest worker's result is used.
TEST(FarmVerification, NonFiniteResultsAreRefused) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--max-attempts", "3"});
  RenderClient client = coordinator.Client();
  auto liar = StartLiar(dir, coordinator.address(), "nan");
  WaitForWorkers(client, 1);
  auto honest = StartWorker(dir, coordinator.address());
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator.address(), "--wait",
                                     "--quiet", "--out", dir.Path("farm.exr")};
  submit.insert(submit.end(), kJob.begin(), kJob.end());
  CliResult r = RunCli(dir, submit);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("farm.exr")), Embedded(dir)));
  const auto stats = nlohmann::json::parse(Slurp(dir.Path("farm.json")));
  EXPECT_EQ(stats["film"]["nan_samples"], 0) << stats.dump();
  EXPECT_NE(liar->out().find("not finite"), std::string::npos) << liar->out();
}

// The only live worker fails every task it leases: once it is kept off the job, the job says
// why (`waiting`) and then fails with that reason instead of staying RUNNING with an ETA.
TEST(FarmVerification, AJobNoLiveWorkerMayRunFailsSayingWhy) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--max-attempts", "2", "--lease-timeout", "1"});
  RenderClient client = coordinator.Client();
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator.address()};
  submit.insert(submit.end(), kJob.begin(), kJob.end());
  CliResult r = RunCli(dir, submit);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::string job = r.out;
  while (!job.empty() && job.back() == '\n') job.pop_back();
  v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.state() == v1::JOB_STATE_RUNNING; }, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(st.waiting(), "no live worker is connected");
  auto liar = StartLiar(dir, coordinator.address(), "fail", {"--hold", "2"});
  st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.waiting().rfind("every live worker", 0) == 0; }, 30);
  EXPECT_EQ(st.state(), v1::JOB_STATE_RUNNING) << st.error();
  EXPECT_NE(st.waiting().find("injected failure"), std::string::npos) << st.waiting();
  st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 30);
  EXPECT_EQ(st.state(), v1::JOB_STATE_FAILED);
  EXPECT_NE(st.error().find("every live worker (1)"), std::string::npos) << st.error();
  EXPECT_NE(st.error().find("injected failure"), std::string::npos) << st.error();
  EXPECT_TRUE(coordinator.process().running());
}

// A worker stalled past its lease (SIGSTOP: what a slow or partitioned network looks like to the
// coordinator) loses the lease, but an expiry is no evidence against the worker: with
// --max-attempts 1, counting it as a failure would keep the only worker off the job and fail it.
// The job waits for a live worker, finishes with the embedded render's bits once the worker
// resumes, and the worker has no failure and no block.
TEST(FarmVerification, AnExpiredLeaseIsNotTheWorkersFault) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {"--max-attempts", "1", "--lease-timeout", "1"});
  RenderClient client = coordinator.Client();
  auto worker = StartWorker(dir, coordinator.address());
  WaitForWorkers(client, 1);
  const std::vector<std::string> job_args = {"--method", "brute", "--resolution", "48x48", "--lights", "2000",
                                             "--seed", "9", "--param", "rows_per_slice=128"};
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator.address()};
  submit.insert(submit.end(), job_args.begin(), job_args.end());
  CliResult r = RunCli(dir, submit);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::string job = r.out;
  while (!job.empty() && job.back() == '\n') job.pop_back();

  // Stop the worker while it holds a lease.
  bool stopped = false;
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!stopped && std::chrono::steady_clock::now() < end) {
    for (const v1::WorkerStatus& w : client.ListWorkers())
      if (w.name() == worker->name && !w.lease_id().empty()) {
        worker->Kill(SIGSTOP);
        stopped = true;
      }
    if (!stopped) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(stopped) << "the worker never held a lease";
  std::this_thread::sleep_for(std::chrono::milliseconds(3000));
  v1::JobStatus st = client.GetJob(job);
  EXPECT_EQ(st.state(), v1::JOB_STATE_RUNNING) << st.error();
  EXPECT_EQ(st.waiting(), "no live worker is connected");
  worker->Kill(SIGCONT);
  st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.state() != v1::JOB_STATE_RUNNING; }, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  EXPECT_NE(coordinator.process().err().find("lease expired"), std::string::npos) << "the stall expired no lease";
  for (const v1::WorkerStatus& w : client.ListWorkers()) {
    EXPECT_EQ(w.tasks_failed(), 0u) << w.DebugString();
    EXPECT_TRUE(w.blocked_jobs().empty()) << w.DebugString();
    EXPECT_TRUE(w.blocklisted().empty()) << w.DebugString();
  }
  CliResult f = RunCli(dir, {"fetch", job, "--server", coordinator.address(), "--out", dir.Path("farm.exr")});
  ASSERT_EQ(f.exit_code, 0) << f.err;
  std::vector<std::string> render = {"render", ExampleCornellBox(), "--quiet", "--out", dir.Path("embedded.exr")};
  render.insert(render.end(), job_args.begin(), job_args.end());
  CliResult e = RunCli(dir, render);
  ASSERT_EQ(e.exit_code, 0) << e.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("farm.exr")), ReadImage(dir.Path("embedded.exr"))));
}

}  // namespace test_farm_verification
}  // namespace lightfarm
