// Integrity: a blob whose bytes changed on disk (the coordinator's store, a worker's cache) is
// never served or used. The coordinator quarantines it and says so; a worker fetches it again and
// the job keeps its bits.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <nlohmann/json.hpp>

#include "common/farm/content_hash.h"
#include "coordinator/blob_store.h"
#include "tests/integration/farm_harness.h"

namespace lightfarm {
namespace test_farm_integrity {

using namespace lightfarm::testing;
namespace fs = std::filesystem;

// Flips one byte in the middle of a file, in place.
void FlipByte(const std::string& path) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  ASSERT_TRUE(f) << path;
  f.seekg(0, std::ios::end);
  const std::streamoff size = f.tellg();
  ASSERT_GT(size, 0) << path;
  f.seekg(size / 2);
  char c = 0;
  f.read(&c, 1);
  c = char(c ^ 0x5a);
  f.seekp(size / 2);
  f.write(&c, 1);
}

size_t FilesIn(const std::string& dir) {
  size_t n = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) n += e.is_regular_file() ? 1 : 0;
  return n;
}

TEST(FarmIntegrity, ACorruptedStoreBlobIsQuarantinedNeverReadAndPutRepairsIt) {
  TempDir dir;
  BlobStore store(dir.Path("blobs"), 1 << 20);
  Bytes data(4096);
  for (size_t i = 0; i < data.size(); ++i) data[i] = uint8_t(i * 7 + 3);
  const std::string sha = store.Put(data);
  EXPECT_EQ(store.Get(sha), data);
  EXPECT_TRUE(store.Verify(sha));

  FlipByte(store.Path(sha));
  try {
    store.Get(sha);
    ADD_FAILURE() << "a corrupted blob was read";
  } catch (const BlobCorrupted& e) {
    EXPECT_NE(std::string(e.what()).find("corrupted"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(sha), std::string::npos) << e.what();
  }
  EXPECT_FALSE(store.Has(sha));  // quarantined: missing, so whoever needs it makes it again
  EXPECT_EQ(store.corrupted(), 1u);
  EXPECT_EQ(FilesIn(dir.Path("blobs/quarantine")), 1u);
  EXPECT_THROW(store.Get(sha), std::out_of_range);

  // Put makes it again; a bad copy already there is replaced, not kept.
  EXPECT_EQ(store.Put(data), sha);
  EXPECT_EQ(store.Get(sha), data);
  FlipByte(store.Path(sha));
  EXPECT_EQ(store.Put(data), sha);
  EXPECT_TRUE(store.Verify(sha));
  EXPECT_EQ(store.Get(sha), data);
  EXPECT_EQ(store.corrupted(), 2u);
  EXPECT_EQ(FilesIn(dir.Path("blobs/quarantine")), 2u);
}

// These cases test the checks on read; the background scrub (test_farm_upkeep.cpp) would find
// the flipped bytes first.
const std::vector<std::string> kReadPathOnly = {"--scrub-mb-per-s", "0"};

const std::vector<std::string> kJob = {"--method", "brute", "--resolution", "16x16", "--lights", "500", "--seed", "3"};

// A finished job's result blob changed on the coordinator's disk while it was down: `fetch`
// fails with DATA_LOSS naming the corruption instead of serving the changed image, and the
// coordinator stays up.
TEST(FarmIntegrity, ACorruptedResultIsNeverServed) {
  TempDir dir;
  const std::string state = dir.Path("state");
  auto coordinator = std::make_unique<CoordinatorProcess>(dir, state, kReadPathOnly);
  const int port = coordinator->port();
  auto worker = StartWorker(dir, coordinator->address());
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator->address(), "--wait",
                                     "--quiet", "--out", dir.Path("first.exr")};
  submit.insert(submit.end(), kJob.begin(), kJob.end());
  CliResult first = RunCli(dir, submit);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const std::string job = nlohmann::json::parse(Slurp(dir.Path("first.json")))["farm"]["job_id"];
  std::string sha;
  {
    StateDb db(state + "/state.sqlite");
    sha = db.QueryText("SELECT result_sha FROM jobs WHERE id = " + job);
  }
  ASSERT_EQ(sha.size(), 64u);
  coordinator->process().Kill(SIGKILL);
  coordinator->process().Wait(5);
  FlipByte(state + "/blobs/" + sha);
  coordinator = std::make_unique<CoordinatorProcess>(dir, state, kReadPathOnly, port);

  CliResult fetch = RunCli(dir, {"fetch", job, "--server", coordinator->address(), "--out", dir.Path("again.exr")});
  EXPECT_NE(fetch.exit_code, 0);
  EXPECT_NE(fetch.err.find("DATA_LOSS"), std::string::npos) << fetch.err;
  EXPECT_NE(fetch.err.find("corrupted"), std::string::npos) << fetch.err;
  EXPECT_FALSE(fs::exists(dir.Path("again.exr")));
  EXPECT_NE(fetch.err.find("being made again"), std::string::npos) << fetch.err;
  EXPECT_TRUE(coordinator->process().running());
  EXPECT_EQ(FilesIn(state + "/blobs/quarantine"), 1u);
  // The job is made again from its stored tasks: the same bits, without a new submit.
  RenderClient client = coordinator->Client();
  const v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  CliResult refetch = RunCli(dir, {"fetch", job, "--server", coordinator->address(), "--out", dir.Path("again.exr")});
  ASSERT_EQ(refetch.exit_code, 0) << refetch.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("again.exr")), ReadImage(dir.Path("first.exr"))));
  // The same job submitted again renders the same bits (the bad blob is gone, not reused).
  submit[7] = dir.Path("second.exr");
  CliResult second = RunCli(dir, submit);
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("second.exr")), ReadImage(dir.Path("first.exr"))));
}

// The scene files' blobs, by content hash: what a job uploads of the example scene.
std::set<std::string> SceneBlobs(const std::string& scene) {
  std::set<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(fs::path(scene).parent_path()))
    if (e.is_regular_file()) out.insert(Sha256OfFile(e.path().string()));
  return out;
}

// A task's result blob changed while the coordinator was down after the job finished, and the
// result image with it: the image is made again, the task that lost its result is run again on a
// worker, and the bits are those of the first render.
TEST(FarmIntegrity, ACorruptedTaskResultIsComputedAgain) {
  TempDir dir;
  const std::string state = dir.Path("state");
  auto coordinator = std::make_unique<CoordinatorProcess>(dir, state, kReadPathOnly);
  const int port = coordinator->port();
  auto worker = StartWorker(dir, coordinator->address());
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator->address(), "--wait",
                                     "--quiet", "--out", dir.Path("first.exr"), "--param", "rows_per_slice=64"};
  submit.insert(submit.end(), kJob.begin(), kJob.end());
  CliResult first = RunCli(dir, submit);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const std::string job = nlohmann::json::parse(Slurp(dir.Path("first.json")))["farm"]["job_id"];
  std::string task_sha, result_sha;
  int64_t tasks = 0;
  {
    StateDb db(state + "/state.sqlite");
    tasks = db.Query("SELECT COUNT(*) FROM tasks WHERE job_id = " + job)[0][0];
    task_sha = db.QueryText("SELECT result_sha FROM tasks WHERE job_id = " + job + " ORDER BY task_id DESC LIMIT 1");
    result_sha = db.QueryText("SELECT result_sha FROM jobs WHERE id = " + job);
  }
  ASSERT_GE(tasks, 2);
  coordinator->process().Kill(SIGKILL);
  coordinator->process().Wait(5);
  FlipByte(state + "/blobs/" + task_sha);
  FlipByte(state + "/blobs/" + result_sha);
  coordinator = std::make_unique<CoordinatorProcess>(dir, state, kReadPathOnly, port);
  CliResult fetch = RunCli(dir, {"fetch", job, "--server", coordinator->address(), "--out", dir.Path("again.exr")});
  EXPECT_NE(fetch.err.find("DATA_LOSS"), std::string::npos) << fetch.err;
  RenderClient client = coordinator->Client();
  const v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  EXPECT_EQ(int64_t(st.tasks_completed_total()), 1) << "only the task whose result was lost runs again";
  CliResult refetch = RunCli(dir, {"fetch", job, "--server", coordinator->address(), "--out", dir.Path("again.exr")});
  ASSERT_EQ(refetch.exit_code, 0) << refetch.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("again.exr")), ReadImage(dir.Path("first.exr"))));
  EXPECT_EQ(FilesIn(state + "/blobs/quarantine"), 2u);
}

// The light set and receivers a running job's workers need changed on the coordinator's disk
// before any worker fetched them: the fetch is refused (DATA_LOSS), the coordinator plans the job
// again (which stores them again), the worker hands the task back without counting it as its
// failure, and the job finishes with the embedded render's bits.
TEST(FarmIntegrity, ACorruptedLightSetIsMadeAgainAndNoWorkerIsBlamed) {
  TempDir dir;
  const std::string state = dir.Path("state");
  CoordinatorProcess coordinator(dir, state, kReadPathOnly);
  RenderClient client = coordinator.Client();
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator.address()};
  submit.insert(submit.end(), kJob.begin(), kJob.end());
  CliResult submitted = RunCli(dir, submit);
  ASSERT_EQ(submitted.exit_code, 0) << submitted.err;
  std::string job = submitted.out;
  while (!job.empty() && job.back() == '\n') job.pop_back();
  v1::JobStatus st = WaitForJob(client, job, [](const v1::JobStatus& s) { return s.state() == v1::JOB_STATE_RUNNING; }, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_RUNNING) << st.error();
  const std::set<std::string> scene = SceneBlobs(ExampleCornellBox());
  size_t flipped = 0;
  for (const auto& e : fs::directory_iterator(state + "/blobs"))
    if (e.is_regular_file() && !scene.count(e.path().filename().string())) {
      FlipByte(e.path().string());
      ++flipped;
    }
  ASSERT_GE(flipped, 2u);  // the light set and the receivers
  auto worker = StartWorker(dir, coordinator.address());
  st = WaitForJob(client, job, [](const v1::JobStatus&) { return false; }, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_DONE) << st.error();
  std::vector<std::string> render = {"render", ExampleCornellBox(), "--quiet", "--out", dir.Path("embedded.exr")};
  render.insert(render.end(), kJob.begin(), kJob.end());
  ASSERT_EQ(RunCli(dir, render).exit_code, 0);
  CliResult fetched = RunCli(dir, {"fetch", job, "--server", coordinator.address(), "--out", dir.Path("farm.exr")});
  ASSERT_EQ(fetched.exit_code, 0) << fetched.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("farm.exr")), ReadImage(dir.Path("embedded.exr"))));
  for (const v1::WorkerStatus& w : client.ListWorkers()) EXPECT_EQ(w.tasks_failed(), 0u) << w.name();
  EXPECT_GE(FilesIn(state + "/blobs/quarantine"), 1u);
  EXPECT_NE(coordinator.process().err().find("recomputing"), std::string::npos) << coordinator.process().err();
}

// Every blob in a worker's cache (scene files, light set, receivers) changed between two jobs: a
// worker started on that cache fetches them again, and the job keeps its bits.
TEST(FarmIntegrity, ACorruptedWorkerCacheIsFetchedAgain) {
  TempDir dir;
  CoordinatorProcess coordinator(dir, dir.Path("state"), {});
  const std::string cache = dir.Path("cache");
  auto start_worker = [&](const std::string& log) {
    return std::make_unique<Process>(
        std::vector<std::string>{LIGHTFARM_WORKER_PATH, "--coordinator", coordinator.address(), "--threads", "1",
                                 "--poll-interval", "0.02", "--cache-dir", cache, "--log-level", "warn"},
        dir.Path(log));
  };
  std::vector<std::string> submit = {"submit", ExampleCornellBox(), "--server", coordinator.address(), "--wait",
                                     "--quiet", "--out", dir.Path("first.exr")};
  submit.insert(submit.end(), kJob.begin(), kJob.end());
  {
    auto worker = start_worker("worker-a");
    CliResult first = RunCli(dir, submit);
    ASSERT_EQ(first.exit_code, 0) << first.err;
  }
  size_t flipped = 0;
  for (const auto& e : fs::recursive_directory_iterator(cache))
    if (e.is_regular_file() && IsSha256Hex(e.path().filename().string()) && fs::file_size(e.path()) > 0) {
      FlipByte(e.path().string());
      ++flipped;
    }
  ASSERT_GE(flipped, 3u);  // the scene file, the light set and the receivers at least
  auto worker = start_worker("worker-b");
  submit[7] = dir.Path("second.exr");
  CliResult second = RunCli(dir, submit);
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_TRUE(SameBits(ReadImage(dir.Path("second.exr")), ReadImage(dir.Path("first.exr"))));
  const std::string log = worker->out() + worker->err();
  EXPECT_NE(log.find("is corrupted"), std::string::npos) << log;
}

}  // namespace test_farm_integrity
}  // namespace lightfarm
